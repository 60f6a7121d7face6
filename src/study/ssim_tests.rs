//! Tests of the paper's SSIM (ssim.rs): exact values, cases computed by hand and by an
//! independent NumPy/SciPy implementation, and the changes it must notice.

use super::*;

/// A grey luminance picture from `f(x, y)`.
fn picture(w: usize, h: usize, f: impl Fn(usize, usize) -> f64) -> Vec<f64> {
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| f(x, y))
        .collect()
}

/// A structured scene: rings and a bar, 0..255.
fn scene(w: usize, h: usize) -> Vec<f64> {
    picture(w, h, |x, y| {
        let (dx, dy) = (x as f64 - w as f64 / 2.0, y as f64 - h as f64 / 2.0);
        let r = (dx * dx + dy * dy).sqrt();
        let ring = if (r / 4.0).floor() as i64 % 2 == 0 {
            200.0
        } else {
            60.0
        };
        if (10..14).contains(&x) { 250.0 } else { ring }
    })
}

fn ssim(x: &[f64], y: &[f64], w: usize, h: usize) -> Ssim {
    compare_luminance(x, y, w, h).unwrap()
}

#[test]
fn identical_pictures_score_exactly_one() {
    for (w, h) in [(11, 11), (40, 33), (64, 64)] {
        let x = scene(w, h);
        let s = ssim(&x, &x, w, h);
        assert!((s.mean - 1.0).abs() < 1e-12, "{w}x{h}: {}", s.mean);
        assert!((s.worst_block - 1.0).abs() < 1e-12);
        assert_eq!((s.map_width, s.map_height), (w - 10, h - 10));
    }
}

#[test]
fn an_impulse_against_a_constant_matches_the_formula_worked_by_hand() {
    // x: 0 except 200 at the centre of one 11x11 window; y: 100 everywhere. With w0 the centre
    // weight of the normalised window, mu_x = 200 w0, sigma_x^2 = w0 (1 - w0) 200^2, mu_y = 100,
    // sigma_y = sigma_xy = 0, so SSIM = (2 mu_x mu_y + C1) / (mu_x^2 + mu_y^2 + C1)
    // * C2 / (sigma_x^2 + C2).
    let x = picture(11, 11, |x, y| if (x, y) == (5, 5) { 200.0 } else { 0.0 });
    let y = picture(11, 11, |_, _| 100.0);
    let s1: f64 = (-5..=5).map(|i: i32| (-f64::from(i * i) / 4.5).exp()).sum();
    let w0 = 1.0 / (s1 * s1);
    let (mx, my, vx) = (200.0 * w0, 100.0, w0 * (1.0 - w0) * 40000.0);
    let (c1, c2) = (6.5025, 58.5225);
    let want = (2.0 * mx * my + c1) / (mx * mx + my * my + c1) * c2 / (vx + c2);
    let s = ssim(&x, &y, 11, 11);
    assert_eq!(s.map.len(), 1);
    assert!((s.mean - want).abs() < 1e-12, "{} vs {want}", s.mean);
    // The same number from scipy.signal.convolve2d (tools run on this machine, /tmp/proto).
    assert!((s.mean - 0.006_049_869_484_303_22).abs() < 1e-12);
}

#[test]
fn an_odd_size_matches_an_independent_implementation() {
    // 23x17 (no multiple of the window or the block): the mean and map minimum that a NumPy /
    // SciPy version of the authors' code (convolve2d 'valid') gives for the same two pictures.
    let (w, h) = (23, 17);
    let base = |x: usize, y: usize| (x * 37 + y * 91 + ((x * y) % 13) * 17) % 256;
    let x = picture(w, h, |x, y| base(x, y) as f64);
    let y = picture(w, h, |x, y| {
        ((x * 37 + y * 91 + ((x * y) % 13) * 17 + (x + 2 * y) % 29) % 256) as f64 * 0.9
    });
    let s = ssim(&x, &y, w, h);
    assert_eq!((s.map_width, s.map_height), (13, 7));
    assert!(
        (s.mean - 0.609_265_053_422_554_3).abs() < 1e-12,
        "{}",
        s.mean
    );
    let min = s.map.iter().copied().fold(f64::INFINITY, f64::min);
    assert!((min - 0.206_452_051_060_745_18).abs() < 1e-12, "{min}");
    // Blocks of a 13x7 map: 8x7 and a ragged 5x7; the worst is one of them, above the minimum.
    assert!(s.worst_block >= min && s.worst_block < s.mean.max(1.0));
}

#[test]
fn blurred_shifted_and_darkened_pictures_score_lower() {
    let (w, h) = (64, 48);
    let x = scene(w, h);
    let at = |p: &[f64], x: isize, y: isize| {
        p[(y.clamp(0, h as isize - 1) as usize) * w + x.clamp(0, w as isize - 1) as usize]
    };
    let blurred = picture(w, h, |i, j| {
        let (i, j) = (i as isize, j as isize);
        let mut sum = 0.0;
        for dy in -1..=1 {
            for dx in -1..=1 {
                sum += at(&x, i + dx, j + dy);
            }
        }
        sum / 9.0
    });
    let shifted = picture(w, h, |i, j| at(&x, i as isize - 2, j as isize));
    let darkened = picture(w, h, |i, j| 0.6 * x[j * w + i]);
    for (name, y, below) in [
        ("blurred", &blurred, 0.95),
        ("shifted", &shifted, 0.8),
        ("darkened", &darkened, 0.95),
    ] {
        let s = ssim(&x, y, w, h);
        assert!(s.mean < below, "{name}: {}", s.mean);
        assert!(s.worst_block <= s.mean, "{name}");
        // Symmetric in its arguments.
        assert!((ssim(y, &x, w, h).mean - s.mean).abs() < 1e-12);
    }
}

#[test]
fn a_small_local_change_shows_in_the_worst_block_not_the_mean() {
    let (w, h) = (128, 128);
    let x = scene(w, h);
    // A 6x6 patch gone black at (90, 30).
    let y = picture(w, h, |i, j| {
        if (90..96).contains(&i) && (30..36).contains(&j) {
            0.0
        } else {
            x[j * w + i]
        }
    });
    let s = ssim(&x, &y, w, h);
    assert!(s.mean > 0.98, "the mean barely moves: {}", s.mean);
    assert!(s.worst_block < 0.7, "the block shows it: {}", s.worst_block);
    let (bx, by) = s.worst_block_at;
    assert!(
        (80..100).contains(&bx) && (20..40).contains(&by),
        "{bx},{by}"
    );
}

#[test]
fn flat_pictures_are_finite() {
    let (w, h) = (20, 14);
    let black = picture(w, h, |_, _| 0.0);
    let white = picture(w, h, |_, _| 255.0);
    let grey = picture(w, h, |_, _| 128.0);
    assert_eq!(ssim(&black, &black, w, h).mean, 1.0);
    assert_eq!(ssim(&white, &white, w, h).mean, 1.0);
    let bw = ssim(&black, &white, w, h);
    // (C1) / (255^2 + C1): all luminance, no structure term.
    assert!(
        (bw.mean - 6.5025 / (65025.0 + 6.5025)).abs() < 1e-12,
        "{}",
        bw.mean
    );
    let s = ssim(&grey, &white, w, h);
    assert!(s.mean.is_finite() && s.mean > 0.0 && s.mean < 1.0);
    assert!(s.map.iter().all(|v| v.is_finite()));
}

#[test]
fn rgba_pictures_use_luminance_and_bad_sizes_are_typed_errors() {
    let (w, h) = (12, 11);
    let rgba: Vec<u8> = (0..w * h)
        .flat_map(|i| {
            [
                (i * 7 % 256) as u8,
                (i * 13 % 256) as u8,
                (i % 256) as u8,
                255,
            ]
        })
        .collect();
    let mut other_alpha = rgba.clone();
    for p in other_alpha.chunks_exact_mut(4) {
        p[3] = 0;
    }
    let s = compare_rgba8(&rgba, &other_alpha, w, h).unwrap();
    assert_eq!(s.mean, 1.0, "alpha is ignored");
    let y = luminance(&rgba[..4], 4)[0];
    assert!((y - (0.2126 * 0.0 + 0.7152 * 0.0 + 0.0722 * 0.0)).abs() < 1e-12);
    let y1 = luminance(&rgba[4..8], 4)[0];
    assert!((y1 - (0.2126 * 7.0 + 0.7152 * 13.0 + 0.0722 * 1.0)).abs() < 1e-12);
    assert_eq!(
        compare_rgba8(&rgba, &rgba[4..], w, h),
        Err(SsimError::BufferSize {
            got: rgba.len() - 4,
            want: rgba.len()
        })
    );
    let small = vec![0u8; 10 * 30 * 4];
    assert_eq!(
        compare_rgba8(&small, &small, 10, 30),
        Err(SsimError::TooSmall(10, 30))
    );
    assert_eq!(
        compare_rgba8(&[], &[], 0, 0),
        Err(SsimError::TooSmall(0, 0))
    );
}

#[test]
fn the_map_image_is_white_where_equal() {
    let (w, h) = (16, 16);
    let x = scene(w, h);
    let s = ssim(&x, &x, w, h);
    assert!(s.map_gray8().iter().all(|&v| v == 255));
    assert_eq!(s.map_gray8().len(), 36);
}
