//! Intensity layers (issue 31 item 4): a second or third volume (a statistical map, a PET, a
//! FLAIR) drawn over the first with its own colour map, window, threshold and opacity. This
//! module is the plain data and the one rule that turns a layer value into a colour; the grid
//! and its resampling are `scene::layer_grid`, the GPU side `engine::layers`.
//!
//! Decisions:
//! - **NiiVue's and FSLeyes's rule for a statistical map.** A value `v >= threshold` is drawn with
//!   the positive map at `(v - lo) / (hi - lo)` (clamped); with a negative map, a value
//!   `v <= -threshold` is drawn with it at `(-v - lo) / (hi - lo)`; everything between is not
//!   drawn. The threshold is `lo` unless given, so `z.nii.gz:red-yellow:3.1:8` draws |z| >= 3.1.
//!   A layer's opacity is a blend factor over a slice's grey and an opacity per millimetre in 3D
//!   (as a label overlay's), the same for every drawn sample, so a blob's colour says its value
//!   and its outline says the threshold.
//! - **Colours come from a 256-entry table** per side (RGB8 of the map at `i / 255`, nearest
//!   entry), the same table on the GPU, in the f64 twin and on the slices, so the three agree to
//!   the byte.
//! - **Defaults from the data**: without a window, `hi` is the 99.5th and `lo` the 95th
//!   percentile of |v| over the finite non-zero voxels (the top 5 % shows: hot spots of a map,
//!   not its noise floor); the negative side is drawn (blue-lightblue) when some voxel is at or
//!   below `-lo`, as a two-sided z-map has; `neg=off` hides it.
//! - **Clusters** (`cluster=N`): connected groups of drawn voxels (26-connected, on the layer's
//!   own grid, positive and negative sides apart, as FSL's `cluster`) smaller than N voxels are
//!   removed before drawing (`volume::clusters`); it needs a threshold above 0.
//! - The spec on the command line is `FILE[:colormap[:lo:hi]]` then any of `thr=T`,
//!   `neg=MAP|off`, `cluster=N`, `opacity=A`, separated by `:`; a path that exists as given is
//!   taken whole (a file name may hold a colon).

use std::path::{Path, PathBuf};

/// Layers drawn over a volume at most (the second and third volume).
pub const MAX_LAYERS: usize = 2;

/// Entries of a layer's colour table per side.
pub const LAYER_LUT_ENTRIES: usize = 256;

/// A layer's colour map.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LayerColormap {
    /// Red to yellow (FSL's positive statistics map).
    RedYellow,
    /// Blue to light blue (FSL's negative statistics map).
    BlueLightblue,
    /// Black, red, yellow, white.
    Hot,
    /// Black to white.
    Gray,
    /// Perceptually uniform, dark blue to yellow.
    Viridis,
    /// Perceptually uniform, black to pale yellow through red.
    Inferno,
    /// Dark to light green.
    Green,
}

impl LayerColormap {
    /// Every map, in the order help texts list them.
    pub const ALL: [LayerColormap; 7] = [
        LayerColormap::RedYellow,
        LayerColormap::BlueLightblue,
        LayerColormap::Hot,
        LayerColormap::Gray,
        LayerColormap::Viridis,
        LayerColormap::Inferno,
        LayerColormap::Green,
    ];

    /// The name on the command line, in scene documents and in the viewer.
    pub fn name(self) -> &'static str {
        match self {
            LayerColormap::RedYellow => "red-yellow",
            LayerColormap::BlueLightblue => "blue-lightblue",
            LayerColormap::Hot => "hot",
            LayerColormap::Gray => "gray",
            LayerColormap::Viridis => "viridis",
            LayerColormap::Inferno => "inferno",
            LayerColormap::Green => "green",
        }
    }

    /// The map named `name` (case-insensitive; `grey` too).
    pub fn parse(name: &str) -> Option<LayerColormap> {
        let name = name.trim().to_ascii_lowercase();
        let name = if name == "grey" { "gray" } else { &name };
        LayerColormap::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The colour at `x` in [0, 1] (clamped), RGB in [0, 1], f64.
    pub fn colour(self, x: f64) -> [f64; 3] {
        use super::colormap::Colormap;
        let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
        let ramp =
            |from: [f64; 3], to: [f64; 3]| std::array::from_fn(|c| from[c] + (to[c] - from[c]) * x);
        match self {
            LayerColormap::RedYellow => ramp([1.0, 0.0, 0.0], [1.0, 1.0, 0.0]),
            LayerColormap::BlueLightblue => ramp([0.0, 0.0, 1.0], [0.0, 1.0, 1.0]),
            LayerColormap::Green => ramp([0.0, 0.35, 0.0], [0.6, 1.0, 0.6]),
            LayerColormap::Hot => Colormap::Hot.lookup(x),
            LayerColormap::Gray => Colormap::Gray.lookup(x),
            LayerColormap::Viridis => Colormap::Viridis.lookup(x),
            LayerColormap::Inferno => Colormap::Inferno.lookup(x),
        }
    }

    /// The 256-entry table: RGB8 at `i / 255`, alpha 255 (little-endian words, as GLSL's
    /// `unpackUnorm4x8` reads them).
    pub fn table(self) -> [u32; LAYER_LUT_ENTRIES] {
        std::array::from_fn(|i| {
            let rgb = self.colour(i as f64 / (LAYER_LUT_ENTRIES - 1) as f64);
            let [r, g, b] = rgb.map(|c| (c * 255.0).round().clamp(0.0, 255.0) as u32);
            r | (g << 8) | (b << 16) | (255 << 24)
        })
    }
}

/// How a layer is drawn (module decisions). Values are in the layer's physical units.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerStyle {
    /// The positive side's map.
    pub colormap: LayerColormap,
    /// The value at the map's first colour.
    pub lo: f64,
    /// The value at the map's last colour.
    pub hi: f64,
    /// |v| below it is not drawn (>= 0).
    pub threshold: f64,
    /// The negative side's map; None: values below 0 are not drawn.
    pub negative: Option<LayerColormap>,
    /// Smallest cluster kept, in voxels of the layer's grid (0 or 1: every voxel).
    pub cluster: u32,
    /// Blend factor over a slice, opacity per mm in 3D (0..1).
    pub opacity: f64,
}

/// Why a layer's spec or style cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LayerError {
    /// A malformed spec or an out-of-range setting.
    #[error("{0}")]
    Spec(String),
    /// The layer's affine cannot be inverted.
    #[error("{0}: the layer's affine cannot be inverted")]
    Singular(String),
}

impl LayerStyle {
    /// The style's settings are usable (finite window with lo < hi, threshold >= 0, opacity
    /// 0..1, a cluster size only above a threshold of 0).
    pub fn check(&self) -> Result<(), LayerError> {
        let bad = |m: String| Err(LayerError::Spec(m));
        if !(self.lo.is_finite() && self.hi.is_finite() && self.lo < self.hi) {
            return bad(format!(
                "layer window {}..{}: give finite values with lo < hi",
                self.lo, self.hi
            ));
        }
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return bad(format!(
                "layer threshold {}: give a finite value >= 0 (|v| below it is not drawn)",
                self.threshold
            ));
        }
        if !(0.0..=1.0).contains(&self.opacity) {
            return bad(format!("layer opacity {}: give 0 to 1", self.opacity));
        }
        if self.cluster > 1 && self.threshold <= 0.0 {
            return bad(format!(
                "cluster={}: clusters are groups of voxels above a threshold; give thr= above 0",
                self.cluster
            ));
        }
        Ok(())
    }

    /// The colour (RGB8) and side a value is drawn with, None where it is not drawn: the one
    /// rule of the GPU, the f64 twin and the slices (module decisions).
    pub fn colour_of(&self, v: f64, tables: &LayerTables) -> Option<[u8; 3]> {
        let (table, x) = if v >= self.threshold {
            (&tables.positive, (v - self.lo) / (self.hi - self.lo))
        } else if self.negative.is_some() && v <= -self.threshold {
            (&tables.negative, (-v - self.lo) / (self.hi - self.lo))
        } else {
            return None;
        };
        let word = table[lut_index(x)];
        Some([word as u8, (word >> 8) as u8, (word >> 16) as u8])
    }

    /// Both colour tables (the negative one is the positive map's when there is no negative
    /// side: it is never read then).
    pub fn tables(&self) -> LayerTables {
        LayerTables {
            positive: self.colormap.table(),
            negative: self.negative.unwrap_or(self.colormap).table(),
        }
    }
}

/// The table entry of map position `x` (clamped to [0, 1], NaN reads as 0): the nearest of the
/// 256, `floor(x * 255 + 0.5)`, as the shader computes it.
pub fn lut_index(x: f64) -> usize {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    ((x * (LAYER_LUT_ENTRIES - 1) as f64 + 0.5).floor() as usize).min(LAYER_LUT_ENTRIES - 1)
}

/// A layer's two colour tables.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerTables {
    /// Values >= threshold.
    pub positive: [u32; LAYER_LUT_ENTRIES],
    /// Values <= -threshold (with a negative map).
    pub negative: [u32; LAYER_LUT_ENTRIES],
}

/// What a layer spec asks for; unset fields take the data's defaults
/// ([`LayerSpec::style_for`]).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct LayerSpec {
    /// The layer's file.
    pub path: PathBuf,
    /// Positive map.
    pub colormap: Option<LayerColormap>,
    /// Window.
    pub window: Option<(f64, f64)>,
    /// `thr=`.
    pub threshold: Option<f64>,
    /// `neg=`: Some(None) is `neg=off`.
    pub negative: Option<Option<LayerColormap>>,
    /// `cluster=`.
    pub cluster: Option<u32>,
    /// `opacity=`.
    pub opacity: Option<f64>,
}

/// The data's default window and whether it has a negative side (module decisions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerDefaults {
    /// 95th percentile of |v| over finite non-zero voxels.
    pub lo: f64,
    /// 99.5th percentile of the same.
    pub hi: f64,
    /// Some voxel is at or below -lo.
    pub two_sided: bool,
}

impl LayerSpec {
    /// Parses `FILE[:colormap[:lo:hi]][:key=value...]` (module decisions).
    pub fn parse(text: &str) -> Result<LayerSpec, LayerError> {
        if text.is_empty() {
            return Err(LayerError::Spec(
                "--layer needs FILE[:colormap[:lo:hi]][:thr=T][:neg=MAP|off][:cluster=N][:opacity=A]".into(),
            ));
        }
        if Path::new(text).exists() {
            return Ok(LayerSpec {
                path: text.into(),
                ..LayerSpec::default()
            });
        }
        let mut parts = text.split(':');
        let mut spec = LayerSpec {
            path: parts.next().unwrap_or_default().into(),
            ..LayerSpec::default()
        };
        let (positional, keyed): (Vec<&str>, Vec<&str>) = parts.partition(|p| !p.contains('='));
        spec.read_positional(text, &positional)?;
        for item in keyed {
            spec.read_key(item)?;
        }
        Ok(spec)
    }

    fn read_positional(&mut self, text: &str, items: &[&str]) -> Result<(), LayerError> {
        let map = |name: &str| {
            LayerColormap::parse(name).ok_or_else(|| {
                LayerError::Spec(format!(
                    "{text}: no colour map {name:?} (one of {})",
                    map_names()
                ))
            })
        };
        match items {
            [] => {}
            [name] => self.colormap = Some(map(name)?),
            [name, lo, hi] => {
                self.colormap = Some(map(name)?);
                self.window = Some((number(text, "lo", lo)?, number(text, "hi", hi)?));
            }
            _ => {
                return Err(LayerError::Spec(format!(
                    "{text}: give FILE, FILE:colormap or FILE:colormap:lo:hi, then key=value items"
                )));
            }
        }
        Ok(())
    }

    fn read_key(&mut self, item: &str) -> Result<(), LayerError> {
        let (key, value) = item.split_once('=').unwrap_or((item, ""));
        match key {
            "thr" => self.threshold = Some(number(item, "thr", value)?),
            "opacity" => self.opacity = Some(number(item, "opacity", value)?),
            "cluster" => {
                self.cluster = Some(value.parse().map_err(|_| {
                    LayerError::Spec(format!("{item}: give a whole number of voxels"))
                })?)
            }
            "neg" if value.eq_ignore_ascii_case("off") => self.negative = Some(None),
            "neg" => {
                let map = LayerColormap::parse(value).ok_or_else(|| {
                    LayerError::Spec(format!(
                        "{item}: no colour map {value:?} (one of {}, or off)",
                        map_names()
                    ))
                })?;
                self.negative = Some(Some(map));
            }
            _ => {
                return Err(LayerError::Spec(format!(
                    "{item}: unknown layer setting {key:?} (thr, neg, cluster, opacity)"
                )));
            }
        }
        Ok(())
    }

    /// The style this spec asks for, unset fields from `defaults`; checked.
    pub fn style_for(&self, defaults: &LayerDefaults) -> Result<LayerStyle, LayerError> {
        let (lo, hi) = self.window.unwrap_or((defaults.lo, defaults.hi));
        let threshold = self.threshold.unwrap_or(lo.max(0.0));
        let style = LayerStyle {
            colormap: self.colormap.unwrap_or(LayerColormap::RedYellow),
            lo,
            hi,
            threshold,
            negative: self
                .negative
                .unwrap_or(defaults.two_sided.then_some(LayerColormap::BlueLightblue)),
            cluster: self.cluster.unwrap_or(0),
            opacity: self.opacity.unwrap_or(1.0),
        };
        style.check()?;
        Ok(style)
    }
}

fn number(item: &str, what: &str, text: &str) -> Result<f64, LayerError> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| LayerError::Spec(format!("{item}: {what} {text:?} is not a finite number")))
}

/// The colour maps' names, comma separated (for messages and help).
pub fn map_names() -> String {
    LayerColormap::ALL.map(LayerColormap::name).join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEFAULTS: LayerDefaults = LayerDefaults {
        lo: 2.0,
        hi: 6.0,
        two_sided: true,
    };

    #[test]
    fn a_spec_reads_file_map_window_and_keys() {
        let spec =
            LayerSpec::parse("z.nii.gz:hot:3.1:8:thr=2.3:neg=off:cluster=20:opacity=0.5").unwrap();
        assert_eq!(spec.path, PathBuf::from("z.nii.gz"));
        let style = spec.style_for(&DEFAULTS).unwrap();
        assert_eq!(style.colormap, LayerColormap::Hot);
        assert_eq!((style.lo, style.hi, style.threshold), (3.1, 8.0, 2.3));
        assert_eq!(style.negative, None);
        assert_eq!((style.cluster, style.opacity), (20, 0.5));
    }

    #[test]
    fn defaults_fill_what_the_spec_leaves_out() {
        let style = LayerSpec::parse("pet.nii")
            .unwrap()
            .style_for(&DEFAULTS)
            .unwrap();
        assert_eq!(style.colormap, LayerColormap::RedYellow);
        assert_eq!((style.lo, style.hi, style.threshold), (2.0, 6.0, 2.0));
        assert_eq!(style.negative, Some(LayerColormap::BlueLightblue));
        assert_eq!(style.opacity, 1.0);
    }

    #[test]
    fn bad_specs_are_refused_in_one_line() {
        for bad in [
            "",
            "z.nii:nomap",
            "z.nii:hot:3",
            "z.nii:hot:8:3",
            "z.nii:hot:1:nan",
            "z.nii:thr=-1",
            "z.nii:opacity=2",
            "z.nii:cluster=x",
            "z.nii:colour=red",
            "z.nii:hot:0:1:thr=0:cluster=5",
        ] {
            let result = LayerSpec::parse(bad).and_then(|s| s.style_for(&DEFAULTS));
            let message = result.expect_err(bad).to_string();
            assert!(!message.contains('\n'), "{bad}: {message}");
        }
    }

    #[test]
    fn values_take_the_side_and_entry_the_rule_says() {
        let style = LayerSpec::parse("z:red-yellow:2:6")
            .unwrap()
            .style_for(&DEFAULTS)
            .unwrap();
        let tables = style.tables();
        assert_eq!(style.colour_of(1.9, &tables), None, "below the threshold");
        assert_eq!(style.colour_of(-1.9, &tables), None);
        assert_eq!(style.colour_of(2.0, &tables), Some([255, 0, 0]));
        assert_eq!(style.colour_of(6.0, &tables), Some([255, 255, 0]));
        assert_eq!(
            style.colour_of(60.0, &tables),
            Some([255, 255, 0]),
            "clamped"
        );
        assert_eq!(style.colour_of(-2.0, &tables), Some([0, 0, 255]));
        // Half-way: entry round(0.5 * 255) = 128 of the ramp.
        assert_eq!(style.colour_of(-4.0, &tables), Some([0, 128, 255]));
        let one_sided = LayerStyle {
            negative: None,
            ..style
        };
        assert_eq!(one_sided.colour_of(-4.0, &tables), None);
    }

    #[test]
    fn every_map_is_named_and_parsed_back() {
        for map in LayerColormap::ALL {
            assert_eq!(LayerColormap::parse(map.name()), Some(map));
        }
        assert_eq!(LayerColormap::parse("Grey"), Some(LayerColormap::Gray));
    }
}
