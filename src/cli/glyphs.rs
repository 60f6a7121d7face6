//! Orientation letters (R, L, A, P, S, I) burnt into a slice picture.
//!
//! Decisions:
//! - A 5x7 bitmap font of just these six letters, scaled by whole pixels: no font file, no
//!   dependency, the same pixels on every machine (tests can find them).
//! - Letters are pure yellow (255, 255, 0) with a one-pixel black outline: readable on white
//!   matter and on air, and never mistaken for the greyscale image (R = G != B).
//! - A picture too small for a letter (a side under three glyphs) gets none, and the caller says
//!   so, rather than letters covering the anatomy.

/// Rows of each glyph, 5 bits wide, top row first (bit 4 = leftmost column).
fn glyph(letter: char) -> Option<[u8; 7]> {
    Some(match letter {
        'R' => [
            0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001,
        ],
        'L' => [
            0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111,
        ],
        'A' => [
            0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001,
        ],
        'P' => [
            0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000,
        ],
        'S' => [
            0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110,
        ],
        'I' => [
            0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110,
        ],
        _ => return None,
    })
}

/// The letter colour.
pub const LETTER_RGB: [u8; 3] = [255, 255, 0];

/// Whole-pixel scale of the glyphs for a picture of `width` x `height`: about 1/24 of the
/// shorter side per glyph height, at least 1.
pub fn scale_for(width: u32, height: u32) -> u32 {
    (width.min(height) / 168).max(1)
}

/// Burns `letters` (left, right, top, bottom edge) into `rgba` (`width` x `height`, RGBA8).
/// Returns false, leaving the picture untouched, when it is too small to hold them.
pub fn burn_edge_letters(rgba: &mut [u8], width: u32, height: u32, letters: [char; 4]) -> bool {
    let s = scale_for(width, height);
    let (gw, gh) = (5 * s, 7 * s);
    let margin = s + 1;
    if width < 3 * gw + 2 * margin || height < 3 * gh + 2 * margin {
        return false;
    }
    let places = [
        (margin, (height - gh) / 2),
        (width - margin - gw, (height - gh) / 2),
        ((width - gw) / 2, margin),
        ((width - gw) / 2, height - margin - gh),
    ];
    for (letter, (x0, y0)) in letters.into_iter().zip(places) {
        if let Some(rows) = glyph(letter) {
            draw(rgba, width, height, &rows, s, x0, y0);
        }
    }
    true
}

/// Whether glyph pixel (gx, gy) of `rows` is set (outside the glyph: no).
fn set(rows: &[u8; 7], gx: i64, gy: i64) -> bool {
    (0..5).contains(&gx) && (0..7).contains(&gy) && rows[gy as usize] & (1 << (4 - gx)) != 0
}

/// Draws one glyph at scale `s` with its top-left corner at (x0, y0): the outline first (every
/// pixel within one screen pixel of a set glyph pixel), then the letter.
fn draw(rgba: &mut [u8], width: u32, height: u32, rows: &[u8; 7], s: u32, x0: u32, y0: u32) {
    let (w, h) = (width as i64, height as i64);
    let s = s as i64;
    let covered = |x: i64, y: i64| {
        let (dx, dy) = (x - x0 as i64, y - y0 as i64);
        dx >= 0 && dy >= 0 && set(rows, dx / s, dy / s)
    };
    for y in (y0 as i64 - 1)..=(y0 as i64 + 7 * s) {
        for x in (x0 as i64 - 1)..=(x0 as i64 + 5 * s) {
            if x < 0 || y < 0 || x >= w || y >= h {
                continue;
            }
            let at = 4 * (y * w + x) as usize;
            let colour = if covered(x, y) {
                Some(LETTER_RGB)
            } else if (-1..=1).any(|oy| (-1..=1).any(|ox| covered(x + ox, y + oy))) {
                Some([0, 0, 0])
            } else {
                None
            };
            if let Some(rgb) = colour {
                rgba[at..at + 3].copy_from_slice(&rgb);
                rgba[at + 3] = 255;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn yellow_box(rgba: &[u8], width: u32) -> Option<(u32, u32, u32, u32)> {
        let mut b: Option<(u32, u32, u32, u32)> = None;
        for (n, px) in rgba.chunks_exact(4).enumerate() {
            if px[..3] == LETTER_RGB {
                let (x, y) = (n as u32 % width, n as u32 / width);
                b = Some(b.map_or((x, y, x, y), |(a, c, d, e)| {
                    (a.min(x), c.min(y), d.max(x), e.max(y))
                }));
            }
        }
        b
    }

    #[test]
    fn each_letter_lands_on_its_edge_and_tiny_pictures_get_none() {
        let (w, h) = (64u32, 48u32);
        for (edge, letter) in ['R', 'L', 'A', 'P'].into_iter().enumerate() {
            let mut rgba = vec![128u8; (w * h * 4) as usize];
            let mut letters = [' '; 4];
            letters[edge] = letter;
            assert!(burn_edge_letters(&mut rgba, w, h, letters));
            let (x0, y0, x1, y1) = yellow_box(&rgba, w).unwrap();
            let (cx, cy) = ((x0 + x1) / 2, (y0 + y1) / 2);
            match edge {
                0 => assert!(cx < w / 4 && cy > h / 3 && cy < 2 * h / 3),
                1 => assert!(cx > 3 * w / 4 && cy > h / 3 && cy < 2 * h / 3),
                2 => assert!(cy < h / 4 && cx > w / 3 && cx < 2 * w / 3),
                _ => assert!(cy > 3 * h / 4 && cx > w / 3 && cx < 2 * w / 3),
            }
            assert_eq!((x1 - x0, y1 - y0), (4, 6), "one 5x7 glyph at scale 1");
        }
        let mut small = vec![0u8; 10 * 10 * 4];
        assert!(!burn_edge_letters(&mut small, 10, 10, ['R', 'L', 'A', 'P']));
        assert!(small.iter().all(|&b| b == 0));
    }
}
