//! Tissue classification: per-tissue windows with smooth edges, colours, opacities, switches.
//!
//! The classification function (paper step 4, evaluated per sample in the raymarch and in the
//! f64 reference):
//!
//! ```text
//! w_t(v) = smoothstep(lo_t - e_t, lo_t + e_t, v) * (1 - smoothstep(hi_t - e_t, hi_t + e_t, v))
//! f(v)   = min(1, sum_t visible_t * w_t(v) * opacity_t)        (opacity_t clamped to [0, 1])
//! C_s(v) = sum_t visible_t * w_t(v) * opacity_t * colour_t / sum_t visible_t * w_t(v) * opacity_t
//! ```
//!
//! Smooth edges (width `e` on each side) avoid the staircase a hard window draws on every
//! isosurface of its bounds. A tissue whose peak was not found has no window and never contributes.

/// The tissue classes the renderer knows, in the order of the uniform arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TissueClass {
    /// Cerebrospinal fluid.
    Csf = 0,
    /// Grey matter.
    Gm = 1,
    /// White matter.
    Wm = 2,
    /// Pathology / contrast band (lesions, enhancing vessels), above white matter.
    Pathology = 3,
}

impl TissueClass {
    /// All classes in uniform-array order.
    pub const ALL: [TissueClass; 4] = [
        TissueClass::Csf,
        TissueClass::Gm,
        TissueClass::Wm,
        TissueClass::Pathology,
    ];

    /// Lowercase name as used on the command line (`csf`, `gm`, `wm`, `pathology`).
    pub fn name(self) -> &'static str {
        match self {
            TissueClass::Csf => "csf",
            TissueClass::Gm => "gm",
            TissueClass::Wm => "wm",
            TissueClass::Pathology => "pathology",
        }
    }

    /// Parses a command-line name.
    pub fn parse(text: &str) -> Option<TissueClass> {
        TissueClass::ALL
            .into_iter()
            .find(|t| t.name() == text.trim().to_lowercase())
    }
}

use crate::analysis::TissueWindows;
pub use crate::analysis::Window;

/// Edge half-width of a window set by hand for a tissue that had none (I_norm units).
pub const MANUAL_EDGE: f64 = 0.01;

/// Smallest edge half-width the renderer uses: GLSL's smoothstep is undefined for
/// edge0 >= edge1, so a window with a (nearly) hard edge is drawn with this one.
pub const MIN_EDGE: f64 = 1e-4;

/// The renderer's weight of intensity `v` in `window` (its edge raised to [`MIN_EDGE`]), in
/// [0, 1]; exactly what the raymarch evaluates.
pub fn render_weight(window: &Window, v: f64) -> f64 {
    let e = window.edge.max(MIN_EDGE);
    smoothstep(window.lo - e, window.lo + e, v)
        * (1.0 - smoothstep(window.hi - e, window.hi + e, v))
}

/// GLSL's smoothstep in f64.
pub fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// How one tissue is drawn.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TissueStyle {
    /// Window in I_norm; None when the tissue was not found (never drawn).
    pub window: Option<Window>,
    /// Display colour, RGB in [0, 1].
    pub colour: [f32; 3],
    /// Opacity per millimetre of ray at full window weight and maximal gradient, in [0, 1].
    pub opacity: f32,
    /// On/off switch ("pathological unmasking" toggles these).
    pub visible: bool,
}

/// How the vessel channel is drawn (issue 15 item 3): like a tissue, but its window is on the
/// vesselness (0..1, `passes::vesselness`) instead of I_norm. Whether it is drawn is
/// `Effects::vessels` (it decides a derived volume and a shader variant).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VesselStyle {
    /// Window on the vesselness.
    pub window: Window,
    /// Display colour, RGB in [0, 1].
    pub colour: [f32; 3],
    /// Opacity per millimetre of ray at full window weight and maximal gradient, in [0, 1].
    pub opacity: f32,
}

impl Default for VesselStyle {
    /// Vesselness from 0.4 up (the window's top beyond 1 keeps the strongest tubes), crimson,
    /// opaque. Measured on the phantom (`morphray phantom --dims 96x112x96 --labels`, then
    /// `morphray derive`; this machine, lavapipe): vessel voxels have a median vesselness of
    /// 0.44 (90th percentile 0.75), while the 99th percentile of white matter is 0.41 and of
    /// grey matter 0.29 (gyral crowns are ridges too), so 0.4 keeps most vessel voxels and
    /// drops nearly all parenchyma (`tests/vessel_channel.rs` holds it to that).
    fn default() -> Self {
        VesselStyle {
            window: Window {
                lo: 0.4,
                hi: 2.0,
                edge: 0.05,
            },
            colour: [0.90, 0.10, 0.25],
            opacity: 1.0,
        }
    }
}

/// How the head around an extracted brain is drawn (issue 27): a context layer over the same
/// intensity (I_norm) as the tissues, weighted by `1 - b` where `b` is the brain mask at the
/// sample, while the tissues are weighted by `b`. Drawn only where a brain mask is in use
/// (`Effects::brain` and a head); hidden by default, so a head scan shows its brain.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeadStyle {
    /// Window in I_norm (skin, fat, muscle: everything above the background).
    pub window: Window,
    /// Display colour, RGB in [0, 1].
    pub colour: [f32; 3],
    /// Opacity per millimetre of ray at full window weight and maximal gradient, in [0, 1].
    pub opacity: f32,
    /// On/off (`--tissues head,...`).
    pub visible: bool,
}

impl HeadStyle {
    /// The window over everything brighter than `background` (I_norm), skin-toned, translucent
    /// (0.15 per mm: the face reads as a surface, the brain shows through it), hidden.
    pub fn above(background: f64) -> Self {
        let lo = background.clamp(0.02, 0.9);
        HeadStyle {
            window: Window {
                lo,
                hi: 2.0,
                edge: 0.02,
            },
            colour: [0.93, 0.76, 0.64],
            opacity: 0.15,
            visible: false,
        }
    }
}

/// The head layer as a client asks for it: shown or not, and what it sets by hand; the rest
/// comes from the volume (`HeadStyle::above` its background threshold).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct HeadRecipe {
    /// Draw the head around the brain (`--tissues head,...`).
    pub visible: bool,
    /// Window in I_norm, by hand.
    pub window: Option<(f64, f64)>,
    /// Opacity per mm, by hand.
    pub opacity: Option<f32>,
    /// Colour, by hand.
    pub colour: Option<[f32; 3]>,
}

impl HeadRecipe {
    /// `base` with this recipe's settings.
    pub fn apply(&self, base: HeadStyle) -> HeadStyle {
        let mut style = base;
        style.visible = self.visible;
        if let Some((lo, hi)) = self.window {
            style.window.lo = lo;
            style.window.hi = hi;
        }
        if let Some(opacity) = self.opacity {
            style.opacity = opacity;
        }
        if let Some(colour) = self.colour {
            style.colour = colour;
        }
        style
    }
}

impl Default for HeadStyle {
    fn default() -> Self {
        HeadStyle::above(0.1)
    }
}

/// The four tissue styles, indexed by [`TissueClass`], the vessel channel's and the head's.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Classification {
    /// Styles in [`TissueClass::ALL`] order.
    pub tissues: [TissueStyle; 4],
    /// The vessel channel's style.
    pub vessels: VesselStyle,
    /// The head layer's style (drawn only with a brain mask in use).
    pub head: HeadStyle,
}

impl Classification {
    /// Default colours and opacities around the given windows: CSF blue, GM orange, WM ivory,
    /// pathology red; all visible except pathology.
    ///
    /// Opacities (issue 34): GM and WM opaque (1.0 per mm) so the outer surface of the brain is
    /// a surface, CSF faint (0.05) so it does not veil the cortex. Measured with
    /// `tools/figures/surface_metrics.py` on 256x256 renders (this machine, lavapipe): the
    /// silhouette's 10-90 % edge went from 10.2 to 5.4 px on MNI152 and 9.5 to 8.2 px on the
    /// phantom, sulcal local contrast from 0.075 to 0.104 (MNI152) and 0.117 to 0.158 (phantom)
    /// against the former 0.20 / 0.30 / 0.90.
    pub fn with_windows(windows: [Option<Window>; 4]) -> Self {
        let styles = [
            ([0.30, 0.55, 1.00], 0.05, true),
            ([1.00, 0.55, 0.35], 1.00, true),
            ([0.96, 0.94, 0.82], 1.00, true),
            ([1.00, 0.12, 0.08], 1.00, false),
        ];
        let mut tissues = [TissueStyle {
            window: None,
            colour: [0.0; 3],
            opacity: 0.0,
            visible: false,
        }; 4];
        for (i, (colour, opacity, visible)) in styles.into_iter().enumerate() {
            tissues[i] = TissueStyle {
                window: windows[i],
                colour,
                opacity,
                visible,
            };
        }
        Classification {
            tissues,
            vessels: VesselStyle::default(),
            head: HeadStyle::default(),
        }
    }

    /// The style of one tissue.
    pub fn style(&self, tissue: TissueClass) -> &TissueStyle {
        &self.tissues[tissue as usize]
    }

    /// Sets a tissue's window by hand (the CLI's `--window`, the viewer's bands), keeping its
    /// edge width, or [`MANUAL_EDGE`] when the tissue had no window.
    pub fn set_window(&mut self, tissue: TissueClass, lo: f64, hi: f64) {
        let style = self.style_mut(tissue);
        let edge = style.window.map_or(MANUAL_EDGE, |w| w.edge);
        style.window = Some(Window { lo, hi, edge });
    }

    /// Mutable style of one tissue.
    pub fn style_mut(&mut self, tissue: TissueClass) -> &mut TissueStyle {
        &mut self.tissues[tissue as usize]
    }

    /// Default styles around an analysis result's windows (adaptive or paper preset).
    pub fn from_tissue_windows(windows: &TissueWindows) -> Self {
        Classification::with_windows([windows.csf, windows.gm, windows.wm, windows.pathology])
    }

    /// Sets exactly these tissues visible.
    pub fn show_only(&mut self, visible: &[TissueClass]) {
        for t in TissueClass::ALL {
            self.style_mut(t).visible = visible.contains(&t);
        }
    }

    /// f(v) and C_s(v) of the module docs.
    pub fn classify(&self, v: f64) -> (f64, [f64; 3]) {
        self.classify_with_vessels(v, None)
    }

    /// [`Classification::classify`] with the vessel channel's term when `vesselness` is given
    /// (the vessel channel drawn): one more window-weighted, opacity-weighted colour in the
    /// same sums, so vessels mix with the tissues as the tissues mix with each other.
    pub fn classify_with_vessels(&self, v: f64, vesselness: Option<f64>) -> (f64, [f64; 3]) {
        self.classify_masked(v, vesselness, None)
    }

    /// [`Classification::classify_with_vessels`] inside a brain mask: with `brain = Some(b)`
    /// (the mask at the sample, in [0, 1]) every tissue's weight is multiplied by `b` and the
    /// head layer (when visible) adds its own term weighted by `1 - b`; the vessel channel is not
    /// masked (vessels run outside the brain too). Exactly what classification.glsl evaluates.
    pub fn classify_masked(
        &self,
        v: f64,
        vesselness: Option<f64>,
        brain: Option<f64>,
    ) -> (f64, [f64; 3]) {
        let b = brain.map_or(1.0, |b| b.clamp(0.0, 1.0));
        let mut total = 0.0;
        let mut colour = [0.0; 3];
        if let Some(vesselness) = vesselness {
            let style = &self.vessels;
            let w = render_weight(&style.window, vesselness) * style.opacity.clamp(0.0, 1.0) as f64;
            total += w;
            for (c, s) in colour.iter_mut().zip(style.colour) {
                *c += w * s as f64;
            }
        }
        for style in &self.tissues {
            let Some(window) = style.window else { continue };
            if !style.visible {
                continue;
            }
            let w = b * render_weight(&window, v) * style.opacity.clamp(0.0, 1.0) as f64;
            total += w;
            for (c, s) in colour.iter_mut().zip(style.colour) {
                *c += w * s as f64;
            }
        }
        if brain.is_some() && self.head.visible {
            let head = &self.head;
            let w =
                (1.0 - b) * render_weight(&head.window, v) * head.opacity.clamp(0.0, 1.0) as f64;
            total += w;
            for (c, s) in colour.iter_mut().zip(head.colour) {
                *c += w * s as f64;
            }
        }
        if total <= 0.0 {
            return (0.0, [0.0; 3]);
        }
        (total.min(1.0), colour.map(|c| c / total))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_weight_is_half_at_the_bounds_and_one_inside() {
        let w = Window {
            lo: 0.2,
            hi: 0.4,
            edge: 0.02,
        };
        assert!((render_weight(&w, 0.2) - 0.5).abs() < 1e-12);
        assert!((render_weight(&w, 0.4) - 0.5).abs() < 1e-12);
        assert_eq!(render_weight(&w, 0.3), 1.0);
        assert_eq!(render_weight(&w, 0.1), 0.0);
        assert_eq!(render_weight(&w, 0.5), 0.0);
        let hard = Window {
            lo: 0.2,
            hi: 0.4,
            edge: 0.0,
        };
        assert!(
            (render_weight(&hard, 0.2) - 0.5).abs() < 1e-12,
            "a hard edge gets MIN_EDGE"
        );
    }

    #[test]
    fn hidden_or_missing_tissues_contribute_nothing() {
        let window = Some(Window {
            lo: 0.0,
            hi: 1.0,
            edge: 0.01,
        });
        let mut c = Classification::with_windows([window, None, None, None]);
        assert!(c.classify(0.5).0 > 0.0);
        c.show_only(&[]);
        assert_eq!(c.classify(0.5).0, 0.0);
        c.show_only(&[TissueClass::Gm]);
        assert_eq!(c.classify(0.5).0, 0.0, "GM has no window");
    }

    #[test]
    fn colour_is_the_opacity_weighted_mean() {
        let mut c = Classification::with_windows([
            Some(Window {
                lo: 0.0,
                hi: 1.0,
                edge: 0.01,
            }),
            Some(Window {
                lo: 0.0,
                hi: 1.0,
                edge: 0.01,
            }),
            None,
            None,
        ]);
        c.tissues[0].colour = [1.0, 0.0, 0.0];
        c.tissues[0].opacity = 0.25;
        c.tissues[1].colour = [0.0, 0.0, 1.0];
        c.tissues[1].opacity = 0.75;
        let (f, colour) = c.classify(0.5);
        assert!((f - 1.0).abs() < 1e-12);
        assert!((colour[0] - 0.25).abs() < 1e-12 && (colour[2] - 0.75).abs() < 1e-12);
    }
}
