//! Image error metrics against a reference: max abs, RMSE, PSNR and SSIM.
//!
//! Decisions: RGB only (alpha is 1 everywhere), values compared as they are, the reference
//! clamped to [0, 1] like any displayed image; PSNR with peak 1 from the mean squared error over
//! all channels; SSIM (Wang et al. 2004) on luminance (Rec. 709 weights) with 7x7 uniform windows
//! and the usual constants for a dynamic range of 1, averaged over every window position.

/// Errors of one image against its reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ImageError {
    /// Largest absolute channel difference.
    pub max_abs: f64,
    /// Root mean square channel difference.
    pub rmse: f64,
    /// Peak signal-to-noise ratio in dB (peak 1); 200 dB for identical images.
    pub psnr_db: f64,
    /// Mean structural similarity of the luminance (1 = identical).
    pub ssim: f64,
}

fn luminance(p: &[f64; 4]) -> f64 {
    0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]
}

/// Compares `image` with `reference` (both `width * height` RGBA pixels, rows top to bottom).
pub fn compare(
    image: &[[f64; 4]],
    reference: &[[f64; 4]],
    width: usize,
    height: usize,
) -> ImageError {
    let n = image.len().min(reference.len()).max(1);
    let (mut max_abs, mut sum_sq) = (0.0f64, 0.0f64);
    for (a, b) in image.iter().zip(reference) {
        for c in 0..3 {
            let d = (a[c] - b[c].clamp(0.0, 1.0)).abs();
            max_abs = max_abs.max(d);
            sum_sq += d * d;
        }
    }
    let mse = sum_sq / (3 * n) as f64;
    let psnr_db = if mse > 0.0 {
        (10.0 * (1.0 / mse).log10()).min(200.0)
    } else {
        200.0
    };
    ImageError {
        max_abs,
        rmse: mse.sqrt(),
        psnr_db,
        ssim: ssim(image, reference, width, height),
    }
}

fn ssim(image: &[[f64; 4]], reference: &[[f64; 4]], width: usize, height: usize) -> f64 {
    const WINDOW: usize = 7;
    const C1: f64 = 0.01 * 0.01;
    const C2: f64 = 0.03 * 0.03;
    if width < WINDOW
        || height < WINDOW
        || image.len() < width * height
        || reference.len() < width * height
    {
        // Too small for a window: fall back to one global window.
        return global_ssim(image, reference);
    }
    let x: Vec<f64> = image.iter().map(luminance).collect();
    let y: Vec<f64> = reference
        .iter()
        .map(|p| luminance(&p.map(|v| v.clamp(0.0, 1.0))))
        .collect();
    let mut total = 0.0;
    let mut windows = 0usize;
    for top in 0..=height - WINDOW {
        for left in 0..=width - WINDOW {
            let (mut mx, mut my, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for r in top..top + WINDOW {
                for c in left..left + WINDOW {
                    let (a, b) = (x[r * width + c], y[r * width + c]);
                    mx += a;
                    my += b;
                    sxx += a * a;
                    syy += b * b;
                    sxy += a * b;
                }
            }
            let k = (WINDOW * WINDOW) as f64;
            let (mx, my) = (mx / k, my / k);
            let (vx, vy, cxy) = (sxx / k - mx * mx, syy / k - my * my, sxy / k - mx * my);
            total += ((2.0 * mx * my + C1) * (2.0 * cxy + C2))
                / ((mx * mx + my * my + C1) * (vx + vy + C2));
            windows += 1;
        }
    }
    total / windows.max(1) as f64
}

fn global_ssim(image: &[[f64; 4]], reference: &[[f64; 4]]) -> f64 {
    let n = image.len().min(reference.len()).max(1) as f64;
    let x: Vec<f64> = image.iter().map(luminance).collect();
    let y: Vec<f64> = reference.iter().map(luminance).collect();
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let vx = x.iter().map(|a| (a - mx).powi(2)).sum::<f64>() / n;
    let vy = y.iter().map(|b| (b - my).powi(2)).sum::<f64>() / n;
    let cxy = x
        .iter()
        .zip(&y)
        .map(|(a, b)| (a - mx) * (b - my))
        .sum::<f64>()
        / n;
    let (c1, c2) = (1e-4, 9e-4);
    ((2.0 * mx * my + c1) * (2.0 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, f: impl Fn(usize, usize) -> f64) -> Vec<[f64; 4]> {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let v = f(x, y);
                [v, v, v, 1.0]
            })
            .collect()
    }

    #[test]
    fn identical_images_are_perfect() {
        let a = image(16, 12, |x, y| (x * y) as f64 / 200.0);
        let e = compare(&a, &a, 16, 12);
        assert_eq!((e.max_abs, e.rmse, e.psnr_db), (0.0, 0.0, 200.0));
        assert!((e.ssim - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_uniform_offset_gives_the_expected_psnr_and_lower_ssim() {
        let a = image(16, 16, |x, _| x as f64 / 20.0);
        let b = image(16, 16, |x, _| x as f64 / 20.0 + 0.1);
        let e = compare(&b, &a, 16, 16);
        assert!((e.max_abs - 0.1).abs() < 1e-12 && (e.rmse - 0.1).abs() < 1e-12);
        assert!((e.psnr_db - 20.0).abs() < 1e-9, "{}", e.psnr_db);
        assert!(e.ssim < 1.0);
        let noisy = image(16, 16, |x, y| {
            x as f64 / 20.0 + if (x + y) % 2 == 0 { 0.1 } else { -0.1 }
        });
        assert!(
            compare(&noisy, &a, 16, 16).ssim < e.ssim,
            "structure loss costs more SSIM than an offset"
        );
    }
}
