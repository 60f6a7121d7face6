//! Matcaps (issue 34 item 2): shading by one lookup of the view-space normal in an image of a lit
//! sphere, as NiiVue and MRIcroGL offer (their users bring their own matcap PNGs).
//!
//! Decisions:
//! - **One size on the GPU**: every matcap is resampled on the host to [`MATCAP_SIDE`] squared
//!   RGBA8 texels (256 KiB), so the raymarch's buffer and the memory plan have one fixed size
//!   whatever image a user loads, and a 2048-pixel PNG costs no more than a 64-pixel one. A
//!   matcap is smooth (a lit sphere); 256 texels across resolve its highlight to under 1 degree
//!   of normal direction.
//! - **A storage buffer of packed RGBA8, the nearest texel** (one load and `unpackUnorm4x8`), not
//!   a sampled image: the raymarch's other tables are storage buffers written from the host per
//!   frame slot (engine/matcap.rs follows engine/transfer.rs), and the f64 twin
//!   ([`MatcapImage::sample`]) reads the same bytes by the same rule. Bilinear between texel
//!   centres (four loads) made a matcap frame 1.48x the headlight's on the H200 (MNI152,
//!   1920x1080: 0.956 against 0.647 ms, BENCHMARKS.md); the nearest texel of 256 across is at most
//!   1/256 of the normal's range off, and neighbouring texels of a smooth matcap differ by one or
//!   two levels of 255.
//! - **The lookup**: the normal turned to face the viewer, in camera coordinates
//!   `(n . right, n . up)`, maps to `u = 0.5 + 0.5 x`, `v = 0.5 - 0.5 y` (row 0 is the image's
//!   top), texel `floor(u * side)` clamped to the image. The sample's colour
//!   is multiplied by the matcap's RGB (a grey matcap keeps the tissue colours; a tinted one tints
//!   them), clamped to 1: a matcap's mid-grey is about NiiVue's unlit colour.
//! - **Two built-ins, made here** (no image files to ship or license): `clay` (diffuse from the
//!   upper left with little ambient and a bright rim, no highlight: the folds read by their
//!   shading, the silhouette stays sharp against a dark background) and `shiny` (diffuse with a
//!   white highlight).

/// Texels per side of every matcap as the GPU holds it.
pub const MATCAP_SIDE: u32 = 256;

/// Bytes of the GPU buffer of one matcap.
pub const MATCAP_BYTES: u64 = (MATCAP_SIDE as u64) * (MATCAP_SIDE as u64) * 4;

/// The largest image accepted as a matcap, per side (a 4096-pixel PNG is 64 MiB of RGBA).
pub const MAX_SOURCE_SIDE: u32 = 4096;

/// Names of the built-in matcaps.
pub const BUILT_IN: [&str; 2] = ["clay", "shiny"];

/// Why an image cannot be a matcap.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MatcapError {
    /// Width and height differ.
    #[error(
        "a matcap is a square image of a lit sphere; this one is {width}x{height} (crop it square)"
    )]
    NotSquare {
        /// Pixels across.
        width: u32,
        /// Pixels down.
        height: u32,
    },
    /// Too small or too large.
    #[error("a matcap must be 2 to {max} pixels per side; this one is {side}", max = MAX_SOURCE_SIDE)]
    Size {
        /// Pixels per side.
        side: u32,
    },
    /// The pixel bytes do not match the size.
    #[error("the matcap's pixels are {got} bytes, {expected} expected for {side}x{side} RGBA")]
    Bytes {
        /// Pixels per side.
        side: u32,
        /// Bytes given.
        got: usize,
        /// Bytes a square RGBA8 image of that side has.
        expected: usize,
    },
    /// Neither a built-in name nor an existing file.
    #[error(
        "no built-in matcap is named {0:?} and no such file exists (built in: clay, shiny; or give a PNG file)"
    )]
    UnknownName(String),
    /// The file could not be read as a PNG.
    #[error("matcap: {0}")]
    Read(String),
}

/// A matcap as the GPU reads it: [`MATCAP_SIDE`] squared texels, RGBA8 packed little-endian
/// (`r | g << 8 | b << 16 | a << 24`, what `unpackUnorm4x8` reads), row 0 at the top.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct MatcapImage {
    /// Where it came from (a built-in name or a file name), for messages and provenance.
    pub name: String,
    texels: Vec<u32>,
}

impl Default for MatcapImage {
    /// The `clay` built-in.
    fn default() -> Self {
        sphere("clay", clay)
    }
}

impl MatcapImage {
    /// A built-in matcap by name ([`BUILT_IN`]).
    pub fn built_in(name: &str) -> Result<MatcapImage, MatcapError> {
        match name {
            "clay" => Ok(MatcapImage::default()),
            "shiny" => Ok(sphere("shiny", shiny)),
            other => Err(MatcapError::UnknownName(other.to_string())),
        }
    }

    /// The matcap `spec` names: a built-in ([`BUILT_IN`]) or a PNG file (a square image of a lit
    /// sphere, as NiiVue's and MRIcroGL's matcaps are).
    pub fn load(spec: &str) -> Result<MatcapImage, MatcapError> {
        if BUILT_IN.contains(&spec) {
            return MatcapImage::built_in(spec);
        }
        let path = std::path::Path::new(spec);
        if !path.exists() {
            return Err(MatcapError::UnknownName(spec.to_string()));
        }
        let (width, height, rgba) = crate::files::png::read_rgba8(path, MAX_SOURCE_SIDE)
            .map_err(|e| MatcapError::Read(e.to_string()))?;
        let name = path
            .file_name()
            .map_or_else(|| spec.to_string(), |n| n.to_string_lossy().into_owned());
        MatcapImage::from_rgba(&name, width, height, &rgba)
    }

    /// A matcap from a square RGBA8 image (`rgba` row-major from the top, 4 bytes a pixel),
    /// resampled to [`MATCAP_SIDE`] by averaging the source pixels each texel covers (or
    /// bilinear when the source is smaller).
    pub fn from_rgba(
        name: &str,
        width: u32,
        height: u32,
        rgba: &[u8],
    ) -> Result<MatcapImage, MatcapError> {
        if width != height {
            return Err(MatcapError::NotSquare { width, height });
        }
        let side = width;
        if !(2..=MAX_SOURCE_SIDE).contains(&side) {
            return Err(MatcapError::Size { side });
        }
        let expected = (side as usize) * (side as usize) * 4;
        if rgba.len() != expected {
            return Err(MatcapError::Bytes {
                side,
                got: rgba.len(),
                expected,
            });
        }
        let source = Source { side, rgba };
        let n = MATCAP_SIDE as usize;
        let mut texels = Vec::with_capacity(n * n);
        for y in 0..MATCAP_SIDE {
            for x in 0..MATCAP_SIDE {
                texels.push(pack(source.texel(x, y)));
            }
        }
        Ok(MatcapImage {
            name: name.to_string(),
            texels,
        })
    }

    /// The packed texels, as uploaded.
    pub fn texels(&self) -> &[u32] {
        &self.texels
    }

    /// The bytes of the GPU buffer.
    pub fn bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.texels)
    }

    /// RGB in 0..1 at camera-space normal components `(x, y)` (`n . right`, `n . up`): the texel
    /// they fall in, as the shader's `matcap_rgb` (the f64 twin).
    pub fn sample(&self, x: f64, y: f64) -> [f64; 3] {
        let side = f64::from(MATCAP_SIDE);
        let index = |t: f64| ((t * side).floor().max(0.0) as usize).min(MATCAP_SIDE as usize - 1);
        let (tx, ty) = (index(0.5 + 0.5 * x), index(0.5 - 0.5 * y));
        unpack(self.texels[ty * MATCAP_SIDE as usize + tx])
    }
}

/// A square RGBA8 source image.
struct Source<'a> {
    side: u32,
    rgba: &'a [u8],
}

impl Source<'_> {
    fn pixel(&self, x: u32, y: u32) -> [f64; 3] {
        let i = ((y as usize) * (self.side as usize) + x as usize) * 4;
        [0, 1, 2].map(|c| f64::from(self.rgba[i + c]))
    }

    /// The output texel `(x, y)`: the mean of the source pixels it covers when the source is
    /// larger, bilinear between source pixel centres when it is smaller.
    fn texel(&self, x: u32, y: u32) -> [f64; 3] {
        let scale = f64::from(self.side) / f64::from(MATCAP_SIDE);
        if scale >= 1.0 {
            let from = |t: u32| (f64::from(t) * scale).floor() as u32;
            let to = |t: u32| ((f64::from(t + 1) * scale).ceil() as u32).min(self.side);
            let mut sum = [0.0; 3];
            let mut count = 0.0f64;
            for sy in from(y)..to(y) {
                for sx in from(x)..to(x) {
                    let p = self.pixel(sx, sy);
                    (0..3).for_each(|c| sum[c] += p[c]);
                    count += 1.0;
                }
            }
            return sum.map(|s| s / count.max(1.0));
        }
        let last = f64::from(self.side - 1);
        let sx = ((f64::from(x) + 0.5) * scale - 0.5).clamp(0.0, last);
        let sy = ((f64::from(y) + 0.5) * scale - 0.5).clamp(0.0, last);
        let (x0, y0) = (sx.floor() as u32, sy.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(self.side - 1), (y0 + 1).min(self.side - 1));
        let (fx, fy) = (sx - f64::from(x0), sy - f64::from(y0));
        let row = |y: u32| -> [f64; 3] {
            let (a, b) = (self.pixel(x0, y), self.pixel(x1, y));
            std::array::from_fn(|c| a[c] + (b[c] - a[c]) * fx)
        };
        let (a, b) = (row(y0), row(y1));
        std::array::from_fn(|c| a[c] + (b[c] - a[c]) * fy)
    }
}

/// RGB in 0..255 (rounded, clamped) packed with alpha 255.
fn pack(rgb: [f64; 3]) -> u32 {
    let [r, g, b] = rgb.map(|c| c.round().clamp(0.0, 255.0) as u32);
    r | (g << 8) | (b << 16) | (255 << 24)
}

/// RGB in 0..1 of a packed texel.
fn unpack(texel: u32) -> [f64; 3] {
    [0, 8, 16].map(|shift| f64::from((texel >> shift) & 0xff) / 255.0)
}

/// A built-in matcap: `shade` of the unit sphere normal at each texel (outside the disc, the
/// normal at the disc's edge), grey levels in 0..1.
fn sphere(name: &str, shade: impl Fn([f64; 3]) -> [f64; 3]) -> MatcapImage {
    let side = f64::from(MATCAP_SIDE);
    let mut texels = Vec::with_capacity((MATCAP_SIDE * MATCAP_SIDE) as usize);
    for y in 0..MATCAP_SIDE {
        for x in 0..MATCAP_SIDE {
            let nx = (f64::from(x) + 0.5) / side * 2.0 - 1.0;
            let ny = 1.0 - (f64::from(y) + 0.5) / side * 2.0;
            let r = (nx * nx + ny * ny).sqrt();
            let (nx, ny) = if r > 1.0 { (nx / r, ny / r) } else { (nx, ny) };
            let nz = (1.0 - nx * nx - ny * ny).max(0.0).sqrt();
            texels.push(pack(shade([nx, ny, nz]).map(|c| c * 255.0)));
        }
    }
    MatcapImage {
        name: name.to_string(),
        texels,
    }
}

/// The built-ins' light: from the upper left, in front (camera space, unit).
const MATCAP_LIGHT: [f64; 3] = [-0.48, 0.6, 0.64];

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Diffuse with little ambient (the folds' shading carries their contrast) and a bright rim (the
/// silhouette stands out from a dark background instead of fading into it), grey. Tuned on
/// MNI152 at 512x512 with depth cues (`tools/figures/surface_metrics.py`, this machine): the
/// silhouette's 10-90 % rise 4.81 px and sulcal contrast 0.108, against NiiVue's 5.28 px and
/// 0.086 and the studio model's 9.43 px and 0.114. More ambient flattens the folds: ambient 0.42,
/// diffuse 0.5, rim 0.3 (1 - z)^3 gave 2.07 px but 0.061; ambient 0.3, diffuse 0.7, rim 0.35
/// (1 - z)^3 3.89 px and 0.078. The rim keeps the edge sharp, the low ambient the folds.
fn clay(n: [f64; 3]) -> [f64; 3] {
    let diffuse = dot(n, MATCAP_LIGHT).max(0.0);
    let rim = (1.0 - n[2]).powi(5);
    let v = (0.15 + 0.85 * diffuse + 0.55 * rim).min(1.0);
    [v; 3]
}

/// Diffuse with a white highlight, grey.
fn shiny(n: [f64; 3]) -> [f64; 3] {
    let diffuse = dot(n, MATCAP_LIGHT).max(0.0);
    let h = [MATCAP_LIGHT[0], MATCAP_LIGHT[1], MATCAP_LIGHT[2] + 1.0];
    let len = dot(h, h).sqrt();
    let highlight = (dot(n, h) / len).max(0.0).powi(48);
    let v = (0.3 + 0.6 * diffuse + 0.7 * highlight).min(1.0);
    [v; 3]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_constant_image_samples_as_its_colour_everywhere() {
        let rgba: Vec<u8> = (0..64 * 64).flat_map(|_| [51u8, 102, 204, 255]).collect();
        let m = MatcapImage::from_rgba("flat", 64, 64, &rgba).unwrap();
        for (x, y) in [(0.0, 0.0), (0.99, -0.99), (-1.0, 1.0), (0.3, 0.7)] {
            let c = m.sample(x, y);
            for (got, want) in c.iter().zip([0.2, 0.4, 0.8]) {
                assert!((got - want).abs() < 1e-12, "{c:?}");
            }
        }
    }

    #[test]
    fn the_top_of_the_image_is_up_and_its_left_is_left() {
        // Left half dark, top half red: a normal pointing up-left reads red and dark.
        let side = 32u32;
        let rgba: Vec<u8> = (0..side * side)
            .flat_map(|i| {
                let (x, y) = (i % side, i / side);
                [
                    if y < side / 2 { 255 } else { 0 },
                    if x < side / 2 { 0 } else { 255 },
                    0,
                    255,
                ]
            })
            .collect();
        let m = MatcapImage::from_rgba("quadrants", side, side, &rgba).unwrap();
        let up_left = m.sample(-0.7, 0.7);
        assert!(up_left[0] > 0.99 && up_left[1] < 0.01, "{up_left:?}");
        let down_right = m.sample(0.7, -0.7);
        assert!(
            down_right[0] < 0.01 && down_right[1] > 0.99,
            "{down_right:?}"
        );
    }

    #[test]
    fn a_large_image_is_averaged_down_and_a_small_one_interpolated() {
        // A 512 checkerboard of single pixels averages to mid-grey at 256.
        let rgba: Vec<u8> = (0..512u32 * 512)
            .flat_map(|i| {
                let v = if (i % 512 + i / 512) % 2 == 0 {
                    0u8
                } else {
                    254
                };
                [v, v, v, 255]
            })
            .collect();
        let m = MatcapImage::from_rgba("checker", 512, 512, &rgba).unwrap();
        assert!(m.texels().iter().all(|&t| t & 0xff == 127), "averaged");
        // A 2-pixel gradient (0 left, 255 right) is monotone across the 256 texels.
        let two = [
            0u8, 0, 0, 255, 255, 255, 255, 255, 0, 0, 0, 255, 255, 255, 255, 255,
        ];
        let m = MatcapImage::from_rgba("ramp", 2, 2, &two).unwrap();
        let row: Vec<u32> = m.texels()[..256].iter().map(|t| t & 0xff).collect();
        assert!(
            row.windows(2).all(|w| w[0] <= w[1]) && row[0] == 0 && row[255] == 255,
            "{row:?}"
        );
    }

    #[test]
    fn bad_images_are_refused_with_the_reason() {
        let px = |n: usize| vec![0u8; n * 4];
        assert!(matches!(
            MatcapImage::from_rgba("wide", 64, 32, &px(64 * 32)),
            Err(MatcapError::NotSquare { .. })
        ));
        assert!(matches!(
            MatcapImage::from_rgba("dot", 1, 1, &px(1)),
            Err(MatcapError::Size { .. })
        ));
        assert!(matches!(
            MatcapImage::from_rgba("short", 8, 8, &px(10)),
            Err(MatcapError::Bytes { .. })
        ));
        assert!(matches!(
            MatcapImage::built_in("velvet"),
            Err(MatcapError::UnknownName(_))
        ));
    }

    #[test]
    fn the_built_ins_are_lit_from_the_upper_left_and_clay_keeps_a_bright_rim() {
        for name in BUILT_IN {
            let m = MatcapImage::built_in(name).unwrap();
            let upper_left = m.sample(-0.45, 0.55)[0];
            let lower_right = m.sample(0.45, -0.55)[0];
            assert!(
                upper_left > lower_right + 0.2,
                "{name}: {upper_left} vs {lower_right}"
            );
        }
        let clay = MatcapImage::built_in("clay").unwrap();
        // The rim at the lower right (away from the light) is brighter than just inside it.
        assert!(clay.sample(0.69, -0.69)[0] > clay.sample(0.5, -0.5)[0]);
    }
}
