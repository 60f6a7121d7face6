//! Siemens mosaics: one DICOM image whose Rows x Columns hold a grid of tiles, each tile a slice
//! (how most Siemens fMRI and diffusion series arrive). Each mosaic file becomes as many frames
//! as it has tiles, each with its own position, so grouping, ordering and layout (`series`)
//! treat them as any other frames.
//!
//! Decisions (the geometry dcm2niix and nibabel give; learnt from their documentation and code,
//! checked against dcm2niix's output in tests/dicom_mosaic.rs and on the public dcm_qa mosaics
//! by tools/reliability/dcm_qa_mosaics.py):
//! - A file is a mosaic when its ImageType holds MOSAIC and it says how many images it holds:
//!   NumberOfImagesInMosaic (0019,100A), else the CSA image header's NumberOfImagesInMosaic.
//!   A MOSAIC without that number is read as one image (as dcm2niix does, with its warning).
//! - Tiles: `ceil(sqrt(n))` per side, row-major from the top left; Rows and Columns must be
//!   whole multiples of it, else the file is refused (its tiles cannot be cut).
//! - ImagePositionPatient of a mosaic is the corner of the whole grid, not of a tile: the
//!   first slice's position is moved by half the grid minus one tile along the rows and the
//!   columns (`(Columns - tile columns) / 2` pixels along the row direction, likewise down).
//! - Slice k lies `k x spacing` from the first along the slice normal: the CSA header's
//!   SliceNormalVector when it has one (Siemens may store slices against row x column, e.g.
//!   sagittal R to L), else row x column. Spacing: SpacingBetweenSlices, else SliceThickness,
//!   else 1 mm (dcm2niix's order of preference).
//! - The CSA header (0029,1010) is parsed defensively: at most 128 tags and 4096 items each,
//!   every length checked against the buffer; anything malformed is as if it were absent.

use super::geometry::{V3, directions, dot, scale};
use super::headers::FrameHeader;

/// The tile grid of a mosaic file.
#[derive(Clone, Debug, PartialEq)]
pub struct Tiles {
    /// Images (slices) the mosaic holds.
    pub images: usize,
    /// Tiles per side of the grid.
    pub per_side: usize,
    /// Rows of the whole mosaic image.
    pub rows: u32,
    /// Columns of the whole mosaic image.
    pub cols: u32,
}

impl Tiles {
    /// Rows of one tile.
    pub fn tile_rows(&self) -> usize {
        self.rows as usize / self.per_side
    }

    /// Columns of one tile.
    pub fn tile_cols(&self) -> usize {
        self.cols as usize / self.per_side
    }

    /// Copies tile `m` (row-major, `bytes_per` bytes a pixel) out of the whole mosaic `data`;
    /// None when `data` is too short.
    pub fn cut(&self, data: &[u8], m: usize, bytes_per: usize) -> Option<Vec<u8>> {
        let (tr, tc) = (self.tile_rows(), self.tile_cols());
        let (grid_row, grid_col) = (m / self.per_side, m % self.per_side);
        let line = self.cols as usize * bytes_per;
        let mut out = Vec::with_capacity(tr * tc * bytes_per);
        for y in 0..tr {
            let start = (grid_row * tr + y) * line + grid_col * tc * bytes_per;
            out.extend_from_slice(data.get(start..start + tc * bytes_per)?);
        }
        Some(out)
    }
}

/// The tiles of a file whose ImageType is `image_type`, from NumberOfImagesInMosaic
/// (`private_count`, (0019,100A)) or the CSA header; Ok(None): not a mosaic.
pub fn tiles(
    image_type: &[String],
    private_count: Option<i64>,
    csa: Option<&[u8]>,
    rows: u32,
    cols: u32,
) -> Result<Option<Tiles>, String> {
    if !image_type.iter().any(|t| t == "MOSAIC") {
        return Ok(None);
    }
    let from_csa = || {
        csa_values(csa?, "NumberOfImagesInMosaic")?
            .first()?
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .map(|v| v.round() as i64)
    };
    let Some(images) = private_count.filter(|n| *n > 0).or_else(from_csa) else {
        return Ok(None);
    };
    if images < 2 {
        return Ok(None);
    }
    let per_side = (images as f64).sqrt().ceil() as usize;
    let fits = images <= 65535
        && per_side > 0
        && (rows as usize).is_multiple_of(per_side)
        && (cols as usize).is_multiple_of(per_side);
    if !fits {
        return Err(format!(
            "ImageType MOSAIC with {images} images cannot be cut from Rows x Columns {rows} x \
             {cols} (a {per_side} x {per_side} grid of whole tiles)"
        ));
    }
    Ok(Some(Tiles {
        images: images as usize,
        per_side,
        rows,
        cols,
    }))
}

/// One frame per tile from the mosaic's own frame header (see the module's decisions).
pub fn frames(
    mosaic: &FrameHeader,
    tiles: &Tiles,
    csa: Option<&[u8]>,
    spacing: f64,
) -> Vec<FrameHeader> {
    let geometry = mosaic.orientation.as_ref().and_then(directions);
    let csa_normal = csa
        .and_then(|c| csa_values(c, "SliceNormalVector"))
        .and_then(|v| {
            let n: Vec<f64> = v.iter().filter_map(|s| s.trim().parse().ok()).collect();
            (n.len() == 3 && n.iter().all(|x: &f64| x.is_finite())).then(|| [n[0], n[1], n[2]])
        });
    let first = match (mosaic.position, geometry) {
        (Some(p), Some((row, col, normal))) => {
            let [ps_row, ps_col] = mosaic.pixel_spacing.unwrap_or([1.0, 1.0]);
            let across = (tiles.cols as f64 - tiles.tile_cols() as f64) / 2.0 * ps_col;
            let down = (tiles.rows as f64 - tiles.tile_rows() as f64) / 2.0 * ps_row;
            let corner: V3 = [0, 1, 2].map(|a| p[a] + row[a] * across + col[a] * down);
            // Slices go along the CSA normal's side of row x column.
            let sign = match csa_normal {
                Some(n) if dot(n, normal) < 0.0 => -1.0,
                _ => 1.0,
            };
            Some((corner, scale(normal, sign * spacing)))
        }
        _ => None,
    };
    (0..tiles.images)
        .map(|k| FrameHeader {
            frame: k as u32,
            position: first.map(|(p, step)| [0, 1, 2].map(|a| p[a] + step[a] * k as f64)),
            ..mosaic.clone()
        })
        .collect()
}

/// The values of the CSA header tag `name` (Siemens' "SV10" format: a tag count, then per tag
/// a 64-byte name, VM, VR, SyngoDT, item count, and items of four 32-bit words, the second
/// the value's length, each value padded to 4 bytes). None when absent or malformed.
pub fn csa_values(buf: &[u8], name: &str) -> Option<Vec<String>> {
    let u32_at = |at: usize| -> Option<usize> {
        let b = buf.get(at..at + 4)?;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    if buf.get(0..4)? != b"SV10" {
        return None;
    }
    let tags = u32_at(8)?;
    if !(1..=128).contains(&tags) {
        return None;
    }
    let mut pos = 16usize;
    for _ in 0..tags {
        let tag = buf.get(pos..pos + 84)?;
        let end = tag[..64].iter().position(|&b| b == 0).unwrap_or(64);
        let tag_name = &tag[..end];
        let items = u32_at(pos + 76)?;
        if items > 4096 {
            return None;
        }
        pos += 84;
        let mut values = Vec::new();
        for _ in 0..items {
            let len = u32_at(pos + 4)?;
            pos = pos.checked_add(16)?;
            let value = buf.get(pos..pos.checked_add(len)?)?;
            pos += len.div_ceil(4) * 4;
            if !value.is_empty() {
                let text = String::from_utf8_lossy(value);
                values.push(
                    text.trim_matches(|c: char| c == '\0' || c.is_whitespace())
                        .to_string(),
                );
            }
        }
        if tag_name == name.as_bytes() {
            return Some(values);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A CSA header with one tag of string values.
    fn csa(name: &str, values: &[&str]) -> Vec<u8> {
        let mut b = b"SV10\x04\x03\x02\x01".to_vec();
        b.extend_from_slice(&1u32.to_le_bytes());
        b.extend_from_slice(&77u32.to_le_bytes());
        let mut tag = [0u8; 84];
        tag[..name.len()].copy_from_slice(name.as_bytes());
        tag[76..80].copy_from_slice(&(values.len() as u32).to_le_bytes());
        b.extend_from_slice(&tag);
        for v in values {
            let mut item = [0u8; 16];
            item[4..8].copy_from_slice(&(v.len() as u32 + 1).to_le_bytes());
            b.extend_from_slice(&item);
            let mut value = v.as_bytes().to_vec();
            value.push(0);
            while value.len() % 4 != 0 {
                value.push(0);
            }
            b.extend_from_slice(&value);
        }
        b
    }

    #[test]
    fn csa_values_are_read_and_malformed_headers_are_absent() {
        let b = csa("SliceNormalVector", &["0.0", "0.1", "-0.99"]);
        assert_eq!(
            csa_values(&b, "SliceNormalVector"),
            Some(vec!["0.0".into(), "0.1".into(), "-0.99".into()])
        );
        assert_eq!(csa_values(&b, "NumberOfImagesInMosaic"), None);
        for cut in 0..b.len() {
            assert_eq!(csa_values(&b[..cut], "NumberOfImagesInMosaic"), None);
        }
    }

    #[test]
    fn tiles_need_mosaic_a_count_and_a_whole_grid() {
        let t = |ty: &str, n, r, c| tiles(&[ty.to_string()], n, None, r, c);
        assert_eq!(t("M", Some(4), 64, 64), Ok(None));
        assert_eq!(t("MOSAIC", None, 64, 64), Ok(None));
        let ok = t("MOSAIC", Some(5), 96, 96).unwrap().unwrap();
        assert_eq!((ok.per_side, ok.tile_rows(), ok.tile_cols()), (3, 32, 32));
        assert!(t("MOSAIC", Some(5), 100, 96).unwrap_err().contains("3 x 3"));
        let from_csa = csa("NumberOfImagesInMosaic", &["4"]);
        let n = tiles(&["MOSAIC".into()], None, Some(&from_csa), 8, 8);
        assert_eq!(n.unwrap().unwrap().images, 4);
    }

    #[test]
    fn a_tile_is_cut_row_by_row() {
        let tiles = Tiles {
            images: 3,
            per_side: 2,
            rows: 4,
            cols: 4,
        };
        let data: Vec<u8> = (0..16).collect();
        assert_eq!(tiles.cut(&data, 1, 1), Some(vec![2, 3, 6, 7]));
        assert_eq!(tiles.cut(&data, 2, 1), Some(vec![8, 9, 12, 13]));
        assert_eq!(tiles.cut(&data[..10], 2, 1), None);
    }
}
