//! Structural similarity (SSIM, Wang, Bovik, Sheikh & Simoncelli 2004) of two 8-bit pictures:
//! the perceptual metric of the picture regression tests (tests/pictures.rs).
//!
//! Decisions:
//! - The paper's parameters: an 11x11 circular-symmetric Gaussian window (sigma 1.5, weights
//!   normalised to sum 1), K1 = 0.01, K2 = 0.03, dynamic range L = 255, so C1 = (K1 L)^2 and
//!   C2 = (K2 L)^2. The C terms keep flat windows finite (two flat equal windows score 1).
//! - On luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of the 8-bit sRGB code values (no
//!   linearisation: SSIM was defined on the displayed values), in f64.
//! - "Valid" windows only, as the authors' reference code: the map is (W - 10) x (H - 10), so no
//!   padding rule invents structure at the edges; any size of at least 11x11 works, multiple
//!   of anything or not. Smaller pictures are refused with a typed error.
//! - Besides the mean over the map, the minimum over 8x8 blocks of the map (each block's mean;
//!   the ragged blocks at the right and bottom edges included): a small local regression (a
//!   missing vessel, a wrong colour on one structure) is not averaged away by a large unchanged
//!   background. The Gaussian is separable, so the local moments are two 1-D passes.
//! - `metrics.rs` keeps its own 7x7 uniform SSIM on f64 images for the accuracy sweep; this
//!   file is the paper's SSIM for 8-bit pictures, which the picture tests pin.

/// Side of the Gaussian window, pixels.
pub const WINDOW: usize = 11;
/// Standard deviation of the Gaussian window, pixels.
pub const SIGMA: f64 = 1.5;
/// Side of the blocks whose mean SSIM gives [`Ssim::worst_block`], map pixels.
pub const BLOCK: usize = 8;
const C1: f64 = (0.01 * 255.0) * (0.01 * 255.0);
const C2: f64 = (0.03 * 255.0) * (0.03 * 255.0);

/// Why two pictures could not be compared.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SsimError {
    /// The two pictures differ in size.
    #[error("pictures differ in size: {0}x{1} and {2}x{3}; compare pictures of one size")]
    SizeMismatch(usize, usize, usize, usize),
    /// A buffer does not hold width x height pixels.
    #[error("a picture holds {got} bytes, {want} expected for its size")]
    BufferSize {
        /// Bytes given.
        got: usize,
        /// Bytes width x height x channels needs.
        want: usize,
    },
    /// Smaller than one window.
    #[error("{0}x{1} is smaller than the 11x11 SSIM window; render at least 11x11")]
    TooSmall(usize, usize),
}

/// The SSIM of a picture against a reference: the mean, the worst 8x8 block and the map.
#[derive(Clone, Debug, PartialEq)]
pub struct Ssim {
    /// Mean SSIM over the map (1 = identical).
    pub mean: f64,
    /// Lowest mean SSIM of an 8x8 block of the map.
    pub worst_block: f64,
    /// Top-left corner (x, y) of that block in picture pixels (the map's origin is the centre
    /// of the first window, 5 pixels in).
    pub worst_block_at: (usize, usize),
    /// Map width: picture width - 10.
    pub map_width: usize,
    /// Map height: picture height - 10.
    pub map_height: usize,
    /// SSIM of each window, rows top to bottom.
    pub map: Vec<f64>,
}

impl Ssim {
    /// The map as grey levels (SSIM 1 white, 0 or below black) for a look at where two pictures
    /// differ.
    pub fn map_gray8(&self) -> Vec<u8> {
        self.map
            .iter()
            .map(|s| (s.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect()
    }
}

/// Luminance of 8-bit pixels with `channels` samples each (3 RGB, 4 RGBA; alpha ignored).
pub fn luminance(pixels: &[u8], channels: usize) -> Vec<f64> {
    pixels
        .chunks_exact(channels.max(3))
        .map(|p| 0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2]))
        .collect()
}

/// SSIM of two RGBA8 pictures of `width` x `height` pixels (rows top to bottom).
pub fn compare_rgba8(
    image: &[u8],
    reference: &[u8],
    width: usize,
    height: usize,
) -> Result<Ssim, SsimError> {
    let want = width * height * 4;
    for got in [image.len(), reference.len()] {
        if got != want {
            return Err(SsimError::BufferSize { got, want });
        }
    }
    compare_luminance(
        &luminance(image, 4),
        &luminance(reference, 4),
        width,
        height,
    )
}

/// SSIM of two luminance pictures (0..255) of `width` x `height`.
pub fn compare_luminance(
    x: &[f64],
    y: &[f64],
    width: usize,
    height: usize,
) -> Result<Ssim, SsimError> {
    for got in [x.len(), y.len()] {
        if got != width * height {
            return Err(SsimError::BufferSize {
                got,
                want: width * height,
            });
        }
    }
    if width < WINDOW || height < WINDOW {
        return Err(SsimError::TooSmall(width, height));
    }
    let blur = |f: &dyn Fn(usize) -> f64| {
        let field: Vec<f64> = (0..width * height).map(f).collect();
        filter_valid(&field, width, height)
    };
    let mx = blur(&|i| x[i]);
    let my = blur(&|i| y[i]);
    let sxx = blur(&|i| x[i] * x[i]);
    let syy = blur(&|i| y[i] * y[i]);
    let sxy = blur(&|i| x[i] * y[i]);
    let map: Vec<f64> = (0..mx.len())
        .map(|i| {
            let (a, b) = (mx[i], my[i]);
            let (vx, vy, cxy) = (sxx[i] - a * a, syy[i] - b * b, sxy[i] - a * b);
            ((2.0 * a * b + C1) * (2.0 * cxy + C2)) / ((a * a + b * b + C1) * (vx + vy + C2))
        })
        .collect();
    let (map_width, map_height) = (width - WINDOW + 1, height - WINDOW + 1);
    let mean = map.iter().sum::<f64>() / map.len() as f64;
    let (worst_block, (bx, by)) = worst_block(&map, map_width, map_height);
    Ok(Ssim {
        mean,
        worst_block,
        worst_block_at: (bx + WINDOW / 2, by + WINDOW / 2),
        map_width,
        map_height,
        map,
    })
}

/// The normalised 1-D Gaussian; the 2-D window is its outer product.
fn gaussian() -> [f64; WINDOW] {
    let mut g = [0.0; WINDOW];
    let half = (WINDOW / 2) as f64;
    for (i, w) in g.iter_mut().enumerate() {
        let d = i as f64 - half;
        *w = (-d * d / (2.0 * SIGMA * SIGMA)).exp();
    }
    let sum: f64 = g.iter().sum();
    g.map(|w| w / sum)
}

/// `field` filtered by the 2-D Gaussian at every position where the window fits.
fn filter_valid(field: &[f64], width: usize, height: usize) -> Vec<f64> {
    let g = gaussian();
    let out_w = width - WINDOW + 1;
    let out_h = height - WINDOW + 1;
    let mut rows = vec![0.0; out_w * height];
    for r in 0..height {
        let line = &field[r * width..(r + 1) * width];
        for c in 0..out_w {
            rows[r * out_w + c] = g.iter().zip(&line[c..c + WINDOW]).map(|(w, v)| w * v).sum();
        }
    }
    let mut out = vec![0.0; out_w * out_h];
    for r in 0..out_h {
        for c in 0..out_w {
            out[r * out_w + c] = g
                .iter()
                .enumerate()
                .map(|(k, w)| w * rows[(r + k) * out_w + c])
                .sum();
        }
    }
    out
}

/// The lowest block mean of `map` and the block's top-left map coordinates.
fn worst_block(map: &[f64], width: usize, height: usize) -> (f64, (usize, usize)) {
    let mut worst = (f64::INFINITY, (0, 0));
    for by in (0..height).step_by(BLOCK) {
        for bx in (0..width).step_by(BLOCK) {
            let (x1, y1) = ((bx + BLOCK).min(width), (by + BLOCK).min(height));
            let sum: f64 = (by..y1)
                .flat_map(|r| map[r * width + bx..r * width + x1].iter())
                .sum();
            let mean = sum / ((x1 - bx) * (y1 - by)) as f64;
            if mean < worst.0 {
                worst = (mean, (bx, by));
            }
        }
    }
    worst
}

#[cfg(test)]
#[path = "ssim_tests.rs"]
mod tests;
