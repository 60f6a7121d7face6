//! Orthogonal slices in world orientation: which world plane a slice shows, how its pixels map
//! to world millimetres and to the volume's index space, and which orientation letters its
//! edges carry.
//!
//! Decisions:
//! - Slices are planes of the WORLD (RAS+ mm) frame, not of the voxel grid: axial is z = const,
//!   coronal y = const, sagittal x = const, whatever the affine. An oblique volume is therefore
//!   resliced (the GPU samples the plane through the affine), and the picture is oriented as a
//!   radiologist expects even for a file stored LAS, PSR or tilted.
//! - Screen layout: anterior at the top of axial slices, superior at the top of coronal and
//!   sagittal slices, anterior on the left of sagittal slices (as PACS and Slicer show them).
//!   The convention decides only which side of axial and coronal slices the patient's right is
//!   on: [`Convention::Radiological`] (right on the image's left, as if facing the patient; the
//!   clinical default) or [`Convention::Neurological`] (right on the right).
//! - A slice's pixel grid covers the volume's world bounding box in the two in-plane axes, with
//!   pixel centres at `lo + (i + 0.5) * pixel_mm`, so an axis-aligned volume sliced at its own
//!   spacing puts every pixel centre on a voxel centre (no interpolation blur).
//! - Everything here is f64; the GPU receives the index-space grid ([`IndexGrid`]) in f32.

use super::geometry::VolumeGeometry;
// The index-space grid is what the GPU pass consumes: it lives with the pass (a downward
// import), re-exported here beside the world-space plane it is made from.
pub use crate::passes::slice::IndexGrid;
use glam::DVec3;

/// Which world plane a slice shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Plane {
    /// z = const (RAS superior axis as the normal).
    Axial,
    /// y = const.
    Coronal,
    /// x = const.
    Sagittal,
}

impl Plane {
    /// All three, in the order the viewer lays them out.
    pub const ALL: [Plane; 3] = [Plane::Axial, Plane::Coronal, Plane::Sagittal];

    /// The world axis (0 = x, 1 = y, 2 = z) the plane is normal to.
    pub fn normal_axis(self) -> usize {
        match self {
            Plane::Axial => 2,
            Plane::Coronal => 1,
            Plane::Sagittal => 0,
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Plane::Axial => "axial",
            Plane::Coronal => "coronal",
            Plane::Sagittal => "sagittal",
        }
    }
}

/// Which side of the image the patient's right is on (axial and coronal slices).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Convention {
    /// Patient's right on the image's left (viewed from the feet / from the front), as
    /// radiologists read scans: the clinical default.
    #[default]
    Radiological,
    /// Patient's right on the image's right (viewed from above / from behind).
    Neurological,
}

impl Convention {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Convention::Radiological => "radiological",
            Convention::Neurological => "neurological",
        }
    }

    /// One line saying what the convention means on the image.
    pub fn describe(self) -> &'static str {
        match self {
            Convention::Radiological => "radiological: the patient's right on the image's left",
            Convention::Neurological => "neurological: the patient's right on the image's right",
        }
    }
}

/// World direction of increasing column (`u`) and increasing row (`v`) for a plane, unit length.
pub fn screen_axes(plane: Plane, convention: Convention) -> (DVec3, DVec3) {
    let right_to_left = match convention {
        Convention::Radiological => -DVec3::X,
        Convention::Neurological => DVec3::X,
    };
    match plane {
        Plane::Axial => (right_to_left, -DVec3::Y),
        Plane::Coronal => (right_to_left, -DVec3::Z),
        Plane::Sagittal => (-DVec3::Y, -DVec3::Z),
    }
}

/// The anatomical letter of a world direction's dominant axis (R, L, A, P, S, I).
pub fn letter_of(direction: DVec3) -> char {
    let a = direction.abs();
    let (axis, sign) = if a.x >= a.y && a.x >= a.z {
        (0, direction.x)
    } else if a.y >= a.z {
        (1, direction.y)
    } else {
        (2, direction.z)
    };
    match (axis, sign >= 0.0) {
        (0, true) => 'R',
        (0, false) => 'L',
        (1, true) => 'A',
        (1, false) => 'P',
        (2, true) => 'S',
        _ => 'I',
    }
}

/// Orientation letters of a slice's edges: left, right, top, bottom.
pub fn edge_letters(plane: Plane, convention: Convention) -> [char; 4] {
    let (u, v) = screen_axes(plane, convention);
    [letter_of(-u), letter_of(u), letter_of(-v), letter_of(v)]
}

/// A slice's pixel grid in world millimetres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliceGrid {
    /// The plane shown.
    pub plane: Plane,
    /// The convention it is drawn in.
    pub convention: Convention,
    /// World coordinate of the plane along its normal axis (mm).
    pub position_mm: f64,
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// World position of pixel (0, 0)'s centre.
    pub corner: DVec3,
    /// World step from one column to the next (mm).
    pub u: DVec3,
    /// World step from one row to the next (mm).
    pub v: DVec3,
}

/// Why a slice cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SliceError {
    /// The pixel size is not a positive finite number.
    #[error("the slice's pixel size {0} mm must be a positive number")]
    BadPixel(f64),
    /// The picture would exceed the largest side allowed.
    #[error(
        "a {plane} slice at {pixel_mm} mm per pixel would be {width}x{height} pixels, more than {max} on a side; use a larger pixel size"
    )]
    TooLarge {
        /// The plane.
        plane: &'static str,
        /// Pixel size asked for.
        pixel_mm: f64,
        /// Width it would have.
        width: f64,
        /// Height it would have.
        height: f64,
        /// The limit.
        max: u32,
    },
    /// `--index` past the volume.
    #[error(
        "slice index {index} is outside the volume: its axis closest to the {plane} normal has {count} voxels (0..{last})"
    )]
    IndexOutside {
        /// The plane.
        plane: &'static str,
        /// Index asked for.
        index: i64,
        /// Voxels along that axis.
        count: u32,
        /// The last valid index.
        last: u32,
    },
    /// `--mm` past the volume's extent along the plane's normal.
    #[error(
        "--mm {mm} is outside the volume: along the {plane} normal ({axis}) it spans {lo:.3} to {hi:.3} mm; choose a coordinate in that range (or --index)"
    )]
    MmOutside {
        /// The plane.
        plane: &'static str,
        /// The world axis of its normal (x, y or z).
        axis: char,
        /// Coordinate asked for.
        mm: f64,
        /// The volume's extent along it, voxel edges included.
        lo: f64,
        /// Upper end.
        hi: f64,
    },
}

/// Largest slice side in pixels (16384 is the Vulkan minimum of maxImageDimension2D... and far
/// beyond any scan; a bigger request is a typo in the pixel size).
pub const MAX_SIDE: u32 = 16384;

impl SliceGrid {
    /// The grid of `plane` at `position_mm` covering `geometry`'s world bounding box at
    /// `pixel_mm` per pixel.
    pub fn new(
        geometry: &VolumeGeometry,
        plane: Plane,
        convention: Convention,
        position_mm: f64,
        pixel_mm: f64,
    ) -> Result<SliceGrid, SliceError> {
        if !(pixel_mm.is_finite() && pixel_mm > 0.0) {
            return Err(SliceError::BadPixel(pixel_mm));
        }
        let (lo, hi) = geometry.world_bounds();
        let (u_dir, v_dir) = screen_axes(plane, convention);
        let span = |dir: DVec3| (hi - lo).dot(dir.abs());
        let (w, h) = (span(u_dir) / pixel_mm, span(v_dir) / pixel_mm);
        if !(w <= MAX_SIDE as f64 && h <= MAX_SIDE as f64) {
            return Err(SliceError::TooLarge {
                plane: plane.name(),
                pixel_mm,
                width: w.ceil(),
                height: h.ceil(),
                max: MAX_SIDE,
            });
        }
        // Rounded, not ceiled: a span of 17.0000001 pixels is 17 (f64 noise of the affine).
        let width = (w - 1e-6).ceil().max(1.0) as u32;
        let height = (h - 1e-6).ceil().max(1.0) as u32;
        // The first pixel centre half a pixel inside the box on the side the axis starts from.
        let start = |dir: DVec3| {
            let from = DVec3::select(dir.cmpge(DVec3::ZERO), lo, hi);
            from.dot(dir.abs()) + 0.5 * pixel_mm * dir.dot(DVec3::ONE)
        };
        let mut corner = u_dir.abs() * start(u_dir) + v_dir.abs() * start(v_dir);
        corner[plane.normal_axis()] = position_mm;
        Ok(SliceGrid {
            plane,
            convention,
            position_mm,
            width,
            height,
            corner,
            u: u_dir * pixel_mm,
            v: v_dir * pixel_mm,
        })
    }

    /// World position of the centre of pixel (x, y) (fractional pixels allowed).
    pub fn world_of_pixel(&self, x: f64, y: f64) -> DVec3 {
        self.corner + x * self.u + y * self.v
    }

    /// Whether world point `p` lies within one pixel's size of the slice's plane.
    pub fn is_on_plane(&self, p: DVec3) -> bool {
        let pixel = self.u.length().max(self.v.length());
        (p[self.plane.normal_axis()] - self.position_mm).abs() <= pixel
    }

    /// Pixel coordinates (x, y) of the projection of world point `p` onto the slice.
    pub fn pixel_of_world(&self, p: DVec3) -> (f64, f64) {
        let d = p - self.corner;
        (
            d.dot(self.u) / self.u.length_squared(),
            d.dot(self.v) / self.v.length_squared(),
        )
    }

    /// The grid in `geometry`'s index space.
    pub fn in_index_space(&self, geometry: &VolumeGeometry) -> IndexGrid {
        let point = |p: DVec3| (geometry.world_to_index * p.extend(1.0)).truncate();
        let vector = |d: DVec3| (geometry.world_to_index * d.extend(0.0)).truncate();
        IndexGrid {
            origin: point(self.corner).to_array(),
            du: vector(self.u).to_array(),
            dv: vector(self.v).to_array(),
            width: self.width,
            height: self.height,
        }
    }
}

/// The voxel axis (0, 1, 2) whose world direction is closest to `plane`'s normal: the axis
/// `--index` counts along.
pub fn index_axis(geometry: &VolumeGeometry, plane: Plane) -> usize {
    let normal = plane.normal_axis();
    (0..3)
        .map(|c| {
            let col = geometry.index_to_world.col(c).truncate();
            (c, col[normal].abs() / col.length().max(f64::MIN_POSITIVE))
        })
        .fold(
            (0, -1.0),
            |best, (c, w)| if w > best.1 { (c, w) } else { best },
        )
        .0
}

/// World coordinate along `plane`'s normal of the plane through voxel `index` along
/// [`index_axis`] (the other two indices at the volume's centre).
pub fn position_of_index(
    geometry: &VolumeGeometry,
    plane: Plane,
    index: i64,
) -> Result<f64, SliceError> {
    let axis = index_axis(geometry, plane);
    let count = geometry.dims[axis];
    if index < 0 || index >= count as i64 {
        return Err(SliceError::IndexOutside {
            plane: plane.name(),
            index,
            count,
            last: count.saturating_sub(1),
        });
    }
    let mut p = DVec3::from_array(geometry.dims.map(|d| (d as f64 - 1.0) / 2.0));
    p[axis] = index as f64;
    let world = (geometry.index_to_world * p.extend(1.0)).truncate();
    Ok(world[plane.normal_axis()])
}

/// `mm` as the position of a `plane` slice, when it cuts the volume's world bounding box (voxel
/// edges included, a thousandth of a millimetre of rounding allowed): a plane past it would
/// be an all-black picture.
pub fn position_of_mm(geometry: &VolumeGeometry, plane: Plane, mm: f64) -> Result<f64, SliceError> {
    let (lo, hi) = geometry.world_bounds();
    let axis = plane.normal_axis();
    let (lo, hi) = (lo[axis], hi[axis]);
    if mm.is_finite() && mm >= lo - 1e-3 && mm <= hi + 1e-3 {
        return Ok(mm);
    }
    Err(SliceError::MmOutside {
        plane: plane.name(),
        axis: ['x', 'y', 'z'][axis],
        mm,
        lo,
        hi,
    })
}

/// World coordinate of the volume's centre along `plane`'s normal (the default slice).
pub fn centre_position(geometry: &VolumeGeometry, plane: Plane) -> f64 {
    let (lo, hi) = geometry.world_bounds();
    (lo[plane.normal_axis()] + hi[plane.normal_axis()]) / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diagonal(dims: [u32; 3], s: [f64; 3]) -> VolumeGeometry {
        let mut a = [[0.0; 4]; 4];
        for i in 0..3 {
            a[i][i] = s[i];
        }
        a[3][3] = 1.0;
        VolumeGeometry::new(dims, a).unwrap()
    }

    #[test]
    fn a_plane_outside_the_volume_is_refused_with_its_extent() {
        // 10 voxels of 2 mm from the origin: voxel edges at -1 and 19 mm.
        let g = diagonal([4, 4, 10], [1.0, 1.0, 2.0]);
        assert_eq!(position_of_mm(&g, Plane::Axial, 19.0), Ok(19.0));
        assert_eq!(position_of_mm(&g, Plane::Axial, -1.0), Ok(-1.0));
        let e = position_of_mm(&g, Plane::Axial, 500.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--mm 500 is outside the volume"), "{e}");
        assert!(e.contains("(z) it spans -1.000 to 19.000 mm"), "{e}");
        assert!(position_of_mm(&g, Plane::Sagittal, 3.6).is_err());
    }

    #[test]
    fn letters_follow_the_convention_on_axial_and_coronal_only() {
        use Convention::*;
        assert_eq!(
            edge_letters(Plane::Axial, Radiological),
            ['R', 'L', 'A', 'P']
        );
        assert_eq!(
            edge_letters(Plane::Axial, Neurological),
            ['L', 'R', 'A', 'P']
        );
        assert_eq!(
            edge_letters(Plane::Coronal, Radiological),
            ['R', 'L', 'S', 'I']
        );
        assert_eq!(
            edge_letters(Plane::Coronal, Neurological),
            ['L', 'R', 'S', 'I']
        );
        assert_eq!(
            edge_letters(Plane::Sagittal, Radiological),
            ['A', 'P', 'S', 'I']
        );
        assert_eq!(
            edge_letters(Plane::Sagittal, Neurological),
            ['A', 'P', 'S', 'I']
        );
    }

    #[test]
    fn an_axis_aligned_grid_puts_pixel_centres_on_voxel_centres() {
        let g = diagonal([17, 13, 11], [0.5, 1.0, 3.0]);
        let grid = SliceGrid::new(&g, Plane::Axial, Convention::Radiological, 6.0, 0.5).unwrap();
        // x spans 8.5 mm = 17 pixels; y spans 13 mm = 26 pixels of 0.5 mm.
        assert_eq!((grid.width, grid.height), (17, 26));
        let index = grid.in_index_space(&g);
        // Radiological: the first column is the largest x (the patient's right), voxel 16.
        assert!((index.origin[0] - 16.0).abs() < 1e-12, "{index:?}");
        assert!((index.du[0] + 1.0).abs() < 1e-12);
        // Anterior (largest y) at the top; half-voxel rows along y (1 mm voxels, 0.5 mm pixels).
        assert!((index.origin[1] - 12.25).abs() < 1e-12, "{index:?}");
        assert!((index.dv[1] + 0.5).abs() < 1e-12);
        assert!((index.origin[2] - 2.0).abs() < 1e-12);
        let (x, y) = grid.pixel_of_world(grid.world_of_pixel(3.0, 7.5));
        assert!((x - 3.0).abs() < 1e-12 && (y - 7.5).abs() < 1e-12);
    }

    #[test]
    fn index_and_mm_positions_agree_and_bad_requests_are_errors() {
        let mut a = [[0.0; 4]; 4];
        // Stored LPI-ish: i runs to the left, k down, with an origin.
        a[0][0] = -2.0;
        a[1][1] = 1.0;
        a[2][2] = -1.5;
        a[0][3] = 10.0;
        a[2][3] = 4.0;
        a[3][3] = 1.0;
        let g = VolumeGeometry::new([5, 6, 7], a).unwrap();
        assert_eq!(index_axis(&g, Plane::Sagittal), 0);
        assert_eq!(position_of_index(&g, Plane::Sagittal, 3).unwrap(), 4.0);
        assert_eq!(position_of_index(&g, Plane::Axial, 2).unwrap(), 1.0);
        assert!(matches!(
            position_of_index(&g, Plane::Axial, 7),
            Err(SliceError::IndexOutside { count: 7, .. })
        ));
        assert!(SliceGrid::new(&g, Plane::Axial, Convention::Radiological, 0.0, 0.0).is_err());
        assert!(SliceGrid::new(&g, Plane::Axial, Convention::Radiological, 0.0, 1e-6).is_err());
        assert!(SliceGrid::new(&g, Plane::Axial, Convention::Radiological, 0.0, f64::NAN).is_err());
    }
}
