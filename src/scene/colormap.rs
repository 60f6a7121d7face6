//! Colour maps for MIP/MinIP and, instead of the tissue colours, for DVR.
//!
//! Decisions:
//! - **A table of 16 RGB control points at positions i / 15, linear in between**, the same table
//!   in the uniform block and in the f64 reference, so the GPU and its twin colour alike and a new
//!   map is one table. `gray` is the identity on each channel, computed with the same operations
//!   on the same numbers for R, G and B, so a greyscale image is exactly grey (R = G = B).
//! - `viridis` and `inferno` are matplotlib's maps (Smith, van der Walt, Firing; CC0,
//!   github.com/BIDS/colormap `colormaps.py`), sampled at entries round(i * 255 / 15) of their
//!   256 entries; at 16 points the largest deviation from the 256-entry map is below one 8-bit
//!   level for viridis (the maps are smooth). `hot` and `bone` are the classic piecewise-linear
//!   maps (MATLAB/matplotlib definitions) sampled at the same 16 positions.
//! - The map's input is the display window of the projection modes: `(v - lo) / (hi - lo)`
//!   clamped to [0, 1] (`Scene::intensity_window`), for MIP and MinIP's extreme value and for
//!   each DVR sample's I_norm. In DVR the tissue windows still decide opacity; only the colour
//!   comes from the map.

/// Control points per map.
pub const COLORMAP_POINTS: usize = 16;

/// A colour map by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Colormap {
    /// Black to white.
    Gray,
    /// Black, red, yellow, white.
    Hot,
    /// Perceptually uniform, dark blue to yellow.
    Viridis,
    /// Perceptually uniform, black to pale yellow through red.
    Inferno,
    /// Grey with a blue tint in the shadows (X-ray look).
    Bone,
}

impl Colormap {
    /// Every map, in the order the command line lists them.
    pub const ALL: [Colormap; 5] = [
        Colormap::Gray,
        Colormap::Hot,
        Colormap::Viridis,
        Colormap::Inferno,
        Colormap::Bone,
    ];

    /// The name on the command line and in the viewer.
    pub fn name(self) -> &'static str {
        match self {
            Colormap::Gray => "gray",
            Colormap::Hot => "hot",
            Colormap::Viridis => "viridis",
            Colormap::Inferno => "inferno",
            Colormap::Bone => "bone",
        }
    }

    /// The map named `name` (case-insensitive; `grey` too).
    pub fn parse(name: &str) -> Option<Colormap> {
        let name = name.trim().to_ascii_lowercase();
        if name == "grey" {
            return Some(Colormap::Gray);
        }
        Colormap::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The control points, RGB in [0, 1], at positions i / 15.
    pub fn points(self) -> [[f32; 3]; COLORMAP_POINTS] {
        let at = |i: usize| i as f32 / (COLORMAP_POINTS - 1) as f32;
        match self {
            Colormap::Gray => std::array::from_fn(|i| [at(i); 3]),
            Colormap::Hot => std::array::from_fn(|i| hot(at(i))),
            Colormap::Bone => std::array::from_fn(|i| bone(at(i))),
            Colormap::Viridis => VIRIDIS,
            Colormap::Inferno => INFERNO,
        }
    }

    /// The colour at `x` in [0, 1] (clamped), linear between control points, in f64: the
    /// reference's twin of `colormap_lookup` in `shaders/include/colormap.glsl`.
    pub fn lookup(self, x: f64) -> [f64; 3] {
        lookup_points(&self.points(), x)
    }
}

/// Linear interpolation in a 16-point table at `x` in [0, 1] (clamped; NaN reads as 0).
pub fn lookup_points(points: &[[f32; 3]; COLORMAP_POINTS], x: f64) -> [f64; 3] {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let scaled = x * (COLORMAP_POINTS - 1) as f64;
    let i = (scaled.floor() as usize).min(COLORMAP_POINTS - 2);
    let f = scaled - i as f64;
    std::array::from_fn(|c| {
        let (a, b) = (f64::from(points[i][c]), f64::from(points[i + 1][c]));
        a + (b - a) * f
    })
}

/// matplotlib's `hot`: red rises over [0, 3/8], green over [3/8, 3/4], blue over [3/4, 1].
fn hot(x: f32) -> [f32; 3] {
    let ramp = |lo: f32, hi: f32| ((x - lo) / (hi - lo)).clamp(0.0, 1.0);
    [
        ramp(0.0, 0.375).max(0.0416),
        ramp(0.375, 0.75),
        ramp(0.75, 1.0),
    ]
}

/// matplotlib's `bone`: (7 gray + reversed hot-like blue tint) / 8.
fn bone(x: f32) -> [f32; 3] {
    let ramp = |lo: f32, hi: f32| ((x - lo) / (hi - lo)).clamp(0.0, 1.0);
    // MATLAB's `bone = (7 * gray + fliplr(hot)) / 8`: hot's channels swapped, blue rising first.
    let tint = [ramp(0.75, 1.0), ramp(0.375, 0.75), ramp(0.0, 0.375)];
    std::array::from_fn(|c| (7.0 * x + tint[c]) / 8.0)
}

const VIRIDIS: [[f32; 3]; COLORMAP_POINTS] = [
    [0.267004, 0.004874, 0.329415],
    [0.282656, 0.100196, 0.422160],
    [0.277134, 0.185228, 0.489898],
    [0.253935, 0.265254, 0.529983],
    [0.221989, 0.339161, 0.548752],
    [0.190631, 0.407061, 0.556089],
    [0.163625, 0.471133, 0.558148],
    [0.139147, 0.533812, 0.555298],
    [0.120565, 0.596422, 0.543611],
    [0.134692, 0.658636, 0.517649],
    [0.208030, 0.718701, 0.472873],
    [0.327796, 0.773980, 0.406640],
    [0.477504, 0.821444, 0.318195],
    [0.647257, 0.858400, 0.209861],
    [0.824940, 0.884720, 0.106217],
    [0.993248, 0.906157, 0.143936],
];

const INFERNO: [[f32; 3]; COLORMAP_POINTS] = [
    [0.001462, 0.000466, 0.013866],
    [0.046915, 0.030324, 0.150164],
    [0.142378, 0.046242, 0.308553],
    [0.258234, 0.038571, 0.406485],
    [0.366529, 0.071579, 0.431994],
    [0.472328, 0.110547, 0.428334],
    [0.578304, 0.148039, 0.404411],
    [0.682656, 0.189501, 0.360757],
    [0.780517, 0.243327, 0.299523],
    [0.865006, 0.316822, 0.226055],
    [0.929644, 0.411479, 0.145367],
    [0.970919, 0.522853, 0.058367],
    [0.987622, 0.645320, 0.039886],
    [0.978806, 0.774545, 0.176037],
    [0.950018, 0.903409, 0.380271],
    [0.988362, 0.998364, 0.644924],
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gray_is_exactly_grey_and_the_identity() {
        for i in 0..=1000 {
            let x = f64::from(i) / 1000.0;
            let [r, g, b] = Colormap::Gray.lookup(x);
            assert!(r == g && g == b, "x {x}");
            assert!((r - x).abs() < 1e-6, "x {x} -> {r}");
        }
    }

    #[test]
    fn maps_run_from_their_dark_end_to_their_bright_end() {
        for map in Colormap::ALL {
            let lum = |c: [f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
            assert!(
                lum(map.lookup(0.0)) < 0.1 && lum(map.lookup(1.0)) > 0.8,
                "{}",
                map.name()
            );
            assert_eq!(Colormap::parse(map.name()), Some(map));
        }
        assert_eq!(Colormap::parse("Grey"), Some(Colormap::Gray));
        assert_eq!(Colormap::parse("jet"), None);
        // hot is red at 3/8 and yellow at 3/4.
        let h = Colormap::Hot.lookup(0.375);
        assert!(h[0] > 0.95 && h[1] < 0.06 && h[2] == 0.0, "{h:?}");
        // Out of range and NaN clamp.
        assert_eq!(
            Colormap::Viridis.lookup(-3.0),
            Colormap::Viridis.lookup(0.0)
        );
        assert_eq!(
            Colormap::Viridis.lookup(f64::NAN),
            Colormap::Viridis.lookup(0.0)
        );
        assert_eq!(Colormap::Viridis.lookup(7.0), Colormap::Viridis.lookup(1.0));
    }
}
