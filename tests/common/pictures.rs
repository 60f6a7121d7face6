//! Reading a PNG the tests wrote and counting its pixels by colour, and the adaptive-window scene
//! around a prepared volume: helpers the picture-checking tests share.

use morphray::analysis::analyze;
use morphray::engine::{Engine, PreparedVolume};
use morphray::scene::{Classification, Scene};
use std::path::Path;

/// A decoded PNG: width and RGB pixels, rows top to bottom.
pub struct Picture {
    /// Width in pixels.
    pub width: u32,
    /// RGB per pixel.
    pub pixels: Vec<[u8; 3]>,
}

impl Picture {
    /// Reads the PNG at `path` (panics with the path on failure: a test helper).
    pub fn read(path: &Path) -> Picture {
        let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut reader = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .unwrap();
        let mut rgba = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut rgba).unwrap();
        let channels = info.color_type.samples();
        let pixels = rgba[..info.buffer_size()]
            .chunks_exact(channels)
            .map(|p| [p[0], p[1], p[2]])
            .collect();
        Picture {
            width: info.width,
            pixels,
        }
    }

    /// Indices (x, y) of the pixels inside `rect` ([x, y, w, h]; None: all) passing `keep`.
    pub fn find(&self, rect: Option<[u32; 4]>, keep: impl Fn([u8; 3]) -> bool) -> Vec<(u32, u32)> {
        let height = self.pixels.len() as u32 / self.width;
        let [x0, y0, w, h] = rect.unwrap_or([0, 0, self.width, height]);
        let mut found = Vec::new();
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                if keep(self.pixels[(y * self.width + x) as usize]) {
                    found.push((x, y));
                }
            }
        }
        found
    }
}

/// A pixel whose channel `c` (0 red, 1 green) is bright and at least twice the others.
pub fn dominant(c: usize) -> impl Fn([u8; 3]) -> bool {
    move |p: [u8; 3]| {
        let others = (0..3)
            .filter(|&o| o != c)
            .map(|o| u32::from(p[o]))
            .max()
            .unwrap_or(0);
        p[c] > 40 && u32::from(p[c]) > 2 * others
    }
}

/// `volume` prepared, and the default scene around its adaptive windows seen from azimuth 35,
/// elevation 25 (an oblique view that shows all three axes).
pub fn prepared_scene(
    engine: &mut Engine,
    volume: &morphray::volume::Volume,
) -> (PreparedVolume, Scene) {
    let prepared = engine.prepare(volume).unwrap();
    let (imin, imax) = (
        prepared.normalization.imin.unwrap(),
        prepared.normalization.imax.unwrap(),
    );
    let report = analyze(
        &prepared.histogram,
        imin,
        imax,
        prepared.voxel_count as usize,
        0,
    );
    let mut scene = Scene::new(Classification::from_tissue_windows(
        &report.adaptive_windows,
    ));
    scene.camera.azimuth_deg = 35.0;
    scene.camera.elevation_deg = 25.0;
    (prepared, scene)
}
