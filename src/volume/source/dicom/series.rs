//! Series assembly: image frames grouped into stacks, each stack sorted and checked into a
//! regular 3-D grid.
//!
//! Decisions:
//! - Frames are grouped by SeriesInstanceUID, and one UID is split into stacks wherever its
//!   frames differ in orientation (1e-3), size, pixel spacing, echo or ImageType: a 3-plane
//!   localizer, two echoes or magnitude and phase under one UID become separate stacks.
//! - Roles: ImageType LOCALIZER is a localizer; Secondary Capture SOP classes and
//!   DERIVED\SECONDARY images are derived. Both are listed but never picked by default.
//! - Order is the position along the normal of ImageOrientationPatient (row x column), never
//!   InstanceNumber or file names; spacing is the (lower) median difference of those positions, never
//!   SliceThickness (used only for a single slice).
//! - Checks, and what is done (each leaves a warning on the volume):
//!   - duplicate positions (within 0.01 mm): a file named on the command line, else the first
//!     by InstanceNumber (then file name) is kept, the others are left out and named in the
//!     warning (at most three; a time series of mosaics keeps its first volume this way);
//!   - gaps that differ from the median by more than 1% (or 0.01 mm), which includes missing
//!     slices: the stack is resampled onto a uniform grid of the median spacing by linear
//!     interpolation between the two neighbouring slices (at most 2n+16 slices, else refused);
//!   - gantry tilt (slices offset sideways, angle > 0.01 degree): the affine's slice column
//!     is the mean step between slices, a sheared affine that keeps voxels where they were
//!     scanned (no resampling);
//!   - frames without ImagePositionPatient (more than one) or without a usable
//!     ImageOrientationPatient: the stack is refused (its order would be a guess).

use super::geometry::{V3, affine_ras, directions, dot, norm, scale, sub};
use super::headers::{FileHeader, Scan};
use std::collections::HashMap;

/// Positions closer than this along the normal are the same slice, mm.
const SAME_POSITION_MM: f64 = 0.01;

/// What a stack is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// An acquired image stack: a candidate volume.
    Image,
    /// A localizer (scout): never picked by default.
    Localizer,
    /// A derived secondary capture: never picked by default.
    Derived,
}

/// One frame of a stack: where it is and how to find its pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct Slice {
    /// Index of its file in [`Scan::images`].
    pub file: usize,
    /// Frame inside the file.
    pub frame: u32,
    /// ImagePositionPatient (LPS mm), when present.
    pub position: Option<V3>,
    /// RescaleSlope and RescaleIntercept.
    pub rescale: (f64, f64),
    /// Tie-breaker for duplicates: InstanceNumber.
    pub instance: Option<i64>,
    /// Its file was named on the command line: it wins a tie of positions.
    pub named: bool,
}

/// Frames of one series with one orientation, size and kind: a candidate volume.
#[derive(Clone, Debug)]
pub struct Stack {
    /// SeriesInstanceUID.
    pub uid: String,
    /// SeriesNumber.
    pub number: Option<i64>,
    /// SeriesDescription.
    pub description: String,
    /// Modality.
    pub modality: String,
    /// What it is for.
    pub role: Role,
    /// 1-based position among the stacks of its UID, and how many the UID has.
    pub stack: (usize, usize),
    /// The frames, unordered.
    pub slices: Vec<Slice>,
    /// Distinct files holding them.
    pub files: usize,
    /// The patient frame (FrameOfReferenceUID).
    pub frame_of_reference: String,
    /// A file of the stack, for its shared header facts (encoding, orientation).
    pub first_file: usize,
    /// The regular grid the frames form, or why they form none.
    pub layout: Result<Layout, String>,
}

/// A stack's frames on a regular grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    /// The frames kept, in order along the normal.
    pub order: Vec<Slice>,
    /// When the spacing was not uniform: for each output slice, the two neighbours in `order`
    /// and the weight of the second.
    pub resample: Option<Vec<(usize, usize, f64)>>,
    /// Voxels along i, j, k.
    pub dims: [usize; 3],
    /// Spacing along i, j, k, mm.
    pub spacing: [f64; 3],
    /// Index-to-world, RAS mm.
    pub affine: [[f64; 4]; 4],
    /// What was repaired or found, one sentence each.
    pub warnings: Vec<String>,
}

/// Groups the scan's frames into stacks, sorted by series number, UID and stack, each with its
/// layout.
pub fn stacks(scan: &Scan) -> Vec<Stack> {
    let mut stacks: Vec<Stack> = Vec::new();
    let mut index: HashMap<String, usize> = HashMap::new();
    for (file, h) in scan.images.iter().enumerate() {
        for f in &h.frames {
            let key = split_key(h, f.orientation, f.pixel_spacing);
            let at = *index.entry(key).or_insert_with(|| {
                stacks.push(new_stack(h, file));
                stacks.len() - 1
            });
            stacks[at].slices.push(Slice {
                file,
                frame: f.frame,
                position: f.position,
                rescale: f.rescale,
                instance: h.instance_number,
                named: h.named,
            });
        }
    }
    stacks.sort_by(|a, b| (a.number, &a.uid, a.first_file).cmp(&(b.number, &b.uid, b.first_file)));
    let mut per_uid: HashMap<String, usize> = HashMap::new();
    for s in &stacks {
        *per_uid.entry(s.uid.clone()).or_default() += 1;
    }
    let mut seen: HashMap<String, usize> = HashMap::new();
    for s in &mut stacks {
        let n = seen.entry(s.uid.clone()).or_default();
        *n += 1;
        s.stack = (*n, per_uid[&s.uid]);
        let mut files: Vec<usize> = s.slices.iter().map(|x| x.file).collect();
        files.dedup();
        files.sort_unstable();
        files.dedup();
        s.files = files.len();
        s.layout = layout(&s.slices, scan);
    }
    stacks
}

/// What separates stacks inside one series.
fn split_key(h: &FileHeader, orientation: Option<[f64; 6]>, spacing: Option<[f64; 2]>) -> String {
    let round = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{:.3}", x + 0.0))
            .collect::<Vec<_>>()
            .join(",")
    };
    format!(
        "{}|{}|{}x{}|{}|{}|{}|{}|{}",
        h.series_uid,
        orientation.map(|o| round(&o)).unwrap_or_default(),
        h.rows,
        h.cols,
        spacing.map(|s| round(&s)).unwrap_or_default(),
        h.echo,
        h.image_type.join("\\"),
        h.bits_allocated,
        h.samples_per_pixel
    )
}

/// An empty stack described by its first file.
fn new_stack(h: &FileHeader, file: usize) -> Stack {
    let secondary_capture = h.sop_class.starts_with("1.2.840.10008.5.1.4.1.1.7");
    let derived_secondary = h.image_type.first().is_some_and(|t| t == "DERIVED")
        && h.image_type.iter().any(|t| t == "SECONDARY");
    let role = if h.image_type.iter().any(|t| t == "LOCALIZER") {
        Role::Localizer
    } else if secondary_capture || derived_secondary {
        Role::Derived
    } else {
        Role::Image
    };
    Stack {
        uid: h.series_uid.clone(),
        number: h.series_number,
        description: h.description.clone(),
        modality: h.modality.clone(),
        role,
        stack: (1, 1),
        slices: Vec::new(),
        files: 0,
        frame_of_reference: h.frame_of_reference.clone(),
        first_file: file,
        layout: Err(String::new()),
    }
}

/// The regular grid `slices` form (see the module's decisions).
pub fn layout(slices: &[Slice], scan: &Scan) -> Result<Layout, String> {
    let first = slices.first().ok_or("the stack has no frames")?;
    let h = &scan.images[first.file];
    let f = h
        .frames
        .get(first.frame as usize)
        .ok_or("frame out of range")?;
    if h.samples_per_pixel != 1 {
        return Err(format!(
            "{} samples per pixel (colour): not a grey-scale volume",
            h.samples_per_pixel
        ));
    }
    let (row, col, normal) =
        f.orientation.as_ref().and_then(directions).ok_or(
            "ImageOrientationPatient is missing or unusable, so the slice order is unknown",
        )?;
    let mut warnings = Vec::new();
    let pixel_spacing = match f.pixel_spacing {
        Some(s) if s.iter().all(|v| *v > 0.0) => s,
        _ => {
            warnings.push("PixelSpacing is missing or not positive: 1 mm assumed".into());
            [1.0, 1.0]
        }
    };
    let dims_2d = [h.cols as usize, h.rows as usize];
    if h.mosaic.is_none() && h.image_type.iter().any(|t| t == "MOSAIC") {
        // ImageType says mosaic but neither (0019,100A) nor the CSA header says how many
        // images it holds: the tiles cannot be cut, and a reader must not take it for a slice.
        warnings.push(format!(
            "ImageType says MOSAIC but no NumberOfImagesInMosaic was found (tag 0019,100A or the              CSA header): read as one {}x{} image, not cut into slices; convert it with dcm2niix",
            h.cols, h.rows
        ));
    }
    if slices.len() == 1 {
        let origin = first.position.unwrap_or([0.0; 3]);
        let thickness = h.slice_thickness.unwrap_or(1.0);
        warnings.push(format!(
            "a single slice (a 2-D image): {thickness} mm thickness along the normal"
        ));
        return Ok(Layout {
            order: slices.to_vec(),
            resample: None,
            dims: [dims_2d[0], dims_2d[1], 1],
            spacing: [pixel_spacing[1], pixel_spacing[0], thickness],
            affine: affine_ras(origin, row, col, pixel_spacing, scale(normal, thickness)),
            warnings,
        });
    }
    let missing = slices.iter().filter(|s| s.position.is_none()).count();
    if missing > 0 {
        return Err(format!(
            "{missing} of {} frames have no ImagePositionPatient, so their order is unknown",
            slices.len()
        ));
    }
    let mut order: Vec<(f64, Slice)> = slices
        .iter()
        .map(|s| (dot(s.position.unwrap_or_default(), normal), s.clone()))
        .collect();
    order.sort_by(|a, b| {
        a.0.total_cmp(&b.0)
            .then(b.1.named.cmp(&a.1.named))
            .then(a.1.instance.cmp(&b.1.instance))
            .then(a.1.file.cmp(&b.1.file))
            .then(a.1.frame.cmp(&b.1.frame))
    });
    let before = order.len();
    let mut left_out: Vec<usize> = Vec::new();
    order.dedup_by(|later, kept| {
        let same = (later.0 - kept.0).abs() < SAME_POSITION_MM;
        if same {
            left_out.push(later.1.file);
        }
        same
    });
    if order.len() < before {
        warnings.push(duplicates_warning(before - order.len(), &left_out, scan));
    }
    let dist: Vec<f64> = order.iter().map(|o| o.0).collect();
    let order: Vec<Slice> = order.into_iter().map(|o| o.1).collect();
    let n = order.len();
    if n == 1 {
        return layout(&order, scan);
    }
    let gaps: Vec<f64> = dist.windows(2).map(|w| w[1] - w[0]).collect();
    let mut sorted = gaps.clone();
    sorted.sort_by(f64::total_cmp);
    // The lower median: with few slices and one missing (gaps g and 2g), the upper median
    // would take 2g for the spacing.
    let gap = sorted[(sorted.len() - 1) / 2];
    let tolerance = (0.01 * gap).max(SAME_POSITION_MM);
    let uniform = gaps.iter().all(|g| (g - gap).abs() <= tolerance);
    let first_pos = order[0].position.unwrap_or_default();
    let span = sub(order[n - 1].position.unwrap_or_default(), first_pos);
    let along = dot(span, normal);
    let sideways = norm(sub(span, scale(normal, along)));
    let tilt_deg = sideways.atan2(along).to_degrees();
    // The slice step: the mean step, scaled to the median gap along the normal.
    let step = scale(span, gap / along);
    if tilt_deg.abs() > 0.01 {
        warnings.push(format!(
            "gantry tilt: slices are offset sideways by {tilt_deg:.2} degrees; the affine is \
             sheared to keep each voxel where it was scanned (no resampling)"
        ));
    }
    let mut resample = None;
    let mut slices_out = n;
    if !uniform {
        let m = ((dist[n - 1] - dist[0]) / gap).round() as usize + 1;
        if m > 2 * n + 16 {
            return Err(format!(
                "slice positions are too irregular to resample (gaps from {:.3} to {:.3} mm)",
                sorted[0],
                sorted[sorted.len() - 1]
            ));
        }
        let plan = resample_plan(&dist, gap, m);
        let missing: usize = gaps
            .iter()
            .map(|g| ((g / gap).round() as usize).saturating_sub(1))
            .sum();
        warnings.push(format!(
            "slice spacing is not uniform (gaps {:.3} to {:.3} mm{}): resampled to {m} slices \
             of {gap:.3} mm by linear interpolation between neighbouring slices",
            sorted[0],
            sorted[sorted.len() - 1],
            if missing > 0 {
                format!(", about {missing} slice(s) missing")
            } else {
                String::new()
            }
        ));
        resample = Some(plan);
        slices_out = m;
    }
    Ok(Layout {
        order,
        resample,
        dims: [dims_2d[0], dims_2d[1], slices_out],
        spacing: [pixel_spacing[1], pixel_spacing[0], norm(step)],
        affine: affine_ras(first_pos, row, col, pixel_spacing, step),
        warnings,
    })
}

/// One line: how many frames repeated a position, which rule kept one, and the files left out
/// (at most three named).
fn duplicates_warning(count: usize, left_out: &[usize], scan: &Scan) -> String {
    let mut files = left_out.to_vec();
    files.sort_unstable();
    files.dedup();
    let names: Vec<String> = files
        .iter()
        .take(3)
        .map(|&f| {
            let p = &scan.images[f].path;
            p.file_name()
                .unwrap_or(p.as_os_str())
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    let more = files.len().saturating_sub(3);
    format!(
        "{count} frames repeat another's position (within {SAME_POSITION_MM} mm): at each \
         position the file named on the command line, else the first by InstanceNumber, was \
         kept; left out: {}{}",
        names.join(", "),
        if more > 0 {
            format!(" and {more} more file(s)")
        } else {
            String::new()
        }
    )
}

/// For each of `m` uniform positions from `dist[0]` by `gap`: the neighbours and the weight of
/// the second.
fn resample_plan(dist: &[f64], gap: f64, m: usize) -> Vec<(usize, usize, f64)> {
    let last = dist.len() - 1;
    (0..m)
        .map(|k| {
            let t = dist[0] + k as f64 * gap;
            let b = dist.partition_point(|d| *d <= t).clamp(1, last);
            let a = b - 1;
            let w = ((t - dist[a]) / (dist[b] - dist[a])).clamp(0.0, 1.0);
            (a, b, w)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_slice_is_planned_as_an_interpolation_of_its_neighbours() {
        let plan = resample_plan(&[0.0, 2.0, 6.0, 8.0], 2.0, 5);
        assert_eq!(plan[0], (0, 1, 0.0));
        assert_eq!(plan[1], (1, 2, 0.0));
        assert_eq!(plan[2], (1, 2, 0.5));
        assert_eq!(plan[3], (2, 3, 0.0));
        assert_eq!(plan[4], (2, 3, 1.0));
    }
}
