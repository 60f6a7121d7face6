//! The scene options every rendering command flattens in ([`SceneArgs`]: what `render`,
//! `view`, `bench`, `plan`, `kernels` and `accuracy` accept with the same spelling), their value
//! enums and the parsers of tissue-qualified values (`wm=0.7:0.9`, `csf=0.2`, `gm=#RRGGBB`).

use super::args::{parse_colour, parse_finite, parse_pair, parse_size};
use crate::scene::TissueClass;
use clap::{Args, ValueEnum};

/// Rendering mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ModeArg {
    /// Direct volume rendering: the paper's composite with gradient-modulated opacity.
    Dvr,
    /// Maximum intensity projection.
    Mip,
    /// Minimum intensity projection (ignoring background below the tissue floor).
    Minip,
}

/// Which tissue windows to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WindowsArg {
    /// Placed around the CSF / GM / WM peaks found in this volume's histogram.
    Adaptive,
    /// The paper's fixed constants (CSF 0.05-0.12, GM 0.12-0.18, WM > 0.18, pathology > 0.20):
    /// T1 windows, wrong for a T2 volume.
    Paper,
}

/// An on/off switch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Switch {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

impl Switch {
    /// True for `on`.
    pub fn on(self) -> bool {
        self == Switch::On
    }
}

impl From<bool> for Switch {
    fn from(on: bool) -> Switch {
        if on { Switch::On } else { Switch::Off }
    }
}

/// Projection.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ProjectionArg {
    /// Pinhole camera, 30 degree vertical field of view.
    Perspective,
    /// Parallel rays.
    Orthographic,
}

/// How a sample's tissue windows are evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ClassificationArg {
    /// Two smoothsteps per tissue window per sample (paper eq. 4 as written).
    Exact,
    /// One lookup in a 4096-entry table of the window sums, rebuilt when the windows change.
    Table,
    /// Each voxel classified once into an RGBA8 volume when the windows change; a sample is one
    /// fetch (fastest on CPU devices and iGPUs; 4 bytes a voxel; scenes with a cut use the table).
    Volume,
}

/// The lighting model of shaded DVR (`scene::LightModel`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LightingArg {
    /// A light at the eye: ambient, two-sided diffuse, highlight (the paper's look, cheapest).
    Headlight,
    /// Key light from the upper left, headlight fill, highlight, outlines.
    Studio,
    /// The colour times a matcap image of a lit sphere (--matcap; `clay` by default).
    Matcap,
}

impl LightingArg {
    /// The scene's model.
    pub fn model(self) -> crate::scene::LightModel {
        match self {
            LightingArg::Headlight => crate::scene::LightModel::Headlight,
            LightingArg::Studio => crate::scene::LightModel::Studio,
            LightingArg::Matcap => crate::scene::LightModel::Matcap,
        }
    }
}

/// Source of the gradient term.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum GradientArg {
    /// Computed once into derived volumes (more memory, faster frames).
    Precomputed,
    /// Computed per sample from the intensity volume (no derived memory).
    OnTheFly,
}

/// Storage precision of the derived volumes (gradient magnitude, curvature).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PrecisionArg {
    /// 8-bit SNORM scaled by the volume's maximum: half the memory of f16 and, at the default
    /// step, the same image (ACCURACY.md).
    #[value(name = "8bit")]
    Snorm8,
    /// 16-bit float: for stills at fine steps (84 dB against 70 dB at step 0.125).
    F16,
    /// 32-bit float: the reference precision (no measurable gain over f16).
    F32,
}

/// Everything that defines a rendered image.
#[derive(Debug, Clone, Args, serde::Serialize)]
#[command(next_help_heading = "Scene")]
pub struct SceneArgs {
    /// Image size in pixels, WIDTHxHEIGHT [default: 1024x1024 for render, the window's 1280x800
    /// for view, 1920x1080 for bench, 256x256 for accuracy].
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Camera rotation about the superior axis in degrees: 0 = anterior view (patient's left on
    /// the image's right), 90 = from the patient's right, 180 = posterior.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = parse_finite)]
    pub azimuth: f64,
    /// Camera elevation in degrees above the axial plane (90 = from superior).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = parse_finite)]
    pub elevation: f64,
    /// Magnification; 1 fits the whole volume in the image.
    #[arg(long, default_value_t = 1.0, value_parser = parse_finite)]
    pub zoom: f64,
    /// Move the view by RIGHT,UP millimetres in the image plane.
    #[arg(long, default_value = "0,0", value_parser = parse_pair, allow_hyphen_values = true)]
    pub pan: (f64, f64),
    /// Projection.
    #[arg(long, value_enum, default_value_t = ProjectionArg::Perspective)]
    pub projection: ProjectionArg,
    /// What each ray computes.
    #[arg(long, value_enum, default_value_t = ModeArg::Dvr)]
    pub mode: ModeArg,
    /// Visible tissues: csf, gm, wm, pathology, vessels, head
    ///
    /// Comma-separated.
    ///
    /// `head` draws the skin, fat and muscle around an extracted brain (see --brain) as a
    /// translucent context layer (`--opacity head=0.4`, `--color head=#RRGGBB` style it).
    /// `--tissues pathology` alone "unmasks" lesions and vessels; `vessels` is the vessel
    /// channel, classified on the multi-scale vesselness instead of intensity (computed only when
    /// shown), so `--tissues vessels,pathology` shows the vessels with the brain tissue
    /// suppressed (the paper's Fig. 2). Default: all but pathology and vessels.
    #[arg(long, default_value = "csf,gm,wm", value_delimiter = ',')]
    pub tissues: Vec<String>,
    /// Look by modality: mr, ct, angio, post-contrast, epi; `list` names them
    ///
    /// Default: chosen from what the volume is (angiogram, MR or CT (CTA, angio, AVM in its
    /// name or description, or a contrast agent on a CT): bright band and vesselness, on a CT
    /// in Hounsfield units the 150..600 HU lumen; other CT: bone and vessels in Hounsfield
    /// units; BOLD/ASL: foreground; contrast agent: enhancing band; else mr). The render names it on its `preset:` line. --tissues, --window,
    /// --opacity and --color still apply on top.
    #[arg(long, value_name = "NAME", value_parser = super::preset_arg::parse_preset)]
    pub preset: Option<super::preset_arg::PresetArg>,
    /// Brain extraction: auto (a head scan shows its brain), on, off
    ///
    /// auto finds the brain of an MR head and classifies tissues inside it only, so the scalp
    /// and face do not hide it; a skull-stripped scan is left alone. on uses any brain found;
    /// off classifies every voxel (the face of a head scan). `--tissues head,...` shows the head.
    #[arg(long, default_value = "auto", value_parser = parse_brain)]
    pub brain: crate::passes::brain::BrainSwitch,
    /// Tissue windows: adaptive or paper
    ///
    /// adaptive: around this volume's histogram peaks; paper: the paper's constants.
    #[arg(long, value_enum, default_value_t = WindowsArg::Adaptive)]
    pub windows: WindowsArg,
    /// Sampling distance along each ray, in voxels of the finest axis.
    ///
    /// Smaller is more accurate and slower; opacity is corrected so the image does not darken or
    /// brighten with it.
    #[arg(long, default_value_t = 0.5, value_parser = parse_finite)]
    pub step: f64,
    /// Curvature weight w(k) = 1 + s*tanh(|k|/k_ref) on opacity (paper eq. 4)
    ///
    /// Emphasizes thin, folded structures; computes the Hessian.
    #[arg(long, value_enum, default_value_t = Switch::Off)]
    pub curvature: Switch,
    /// Phong shading with gradient normals: on for `render` and `view`, off for the measuring ones
    ///
    /// Lighting with world-space gradient normals. A still and the viewer's first view are a
    /// shaded surface, at about 11 % of a frame on the H100 (BENCHMARKS.md); the measuring
    /// commands (bench, accuracy) leave it off unless asked.
    #[arg(long, value_enum)]
    pub shading: Option<Switch>,
    /// Lighting: studio (render, view: key light, outlines, depth cues), headlight or matcap
    ///
    /// `studio`: a key light from the upper left with a highlight, a headlight fill, dark
    /// outlines where a surface turns away, and (with --depth-cues, on for render and view)
    /// ambient occlusion and a soft shadow at the visible surface. `headlight`: the paper
    /// renderer's Phong with the light at the eye, the cheapest (`--preset paper` uses it).
    /// `matcap`: the colour times a matcap (an image of a lit sphere looked up by the surface's
    /// direction, as in NiiVue and MRIcroGL; see --matcap). Costs: BENCHMARKS.md "Lighting and
    /// depth cues".
    #[arg(long, value_enum)]
    pub lighting: Option<LightingArg>,
    /// The matcap of `--lighting matcap` (implies it): clay, shiny, or a square PNG file
    ///
    /// `clay` (the default: soft light from the upper left, a light rim) and `shiny` (with a
    /// highlight) are built in; any matcap PNG (NiiVue's, MRIcroGL's) works, resampled to
    /// 256x256. A grey matcap keeps the tissue colours; a tinted one tints them.
    #[arg(long, value_name = "NAME|FILE.png", hide_short_help = true)]
    pub matcap: Option<String>,
    /// Ambient occlusion and a soft shadow toward the key light: on for render and view
    ///
    /// Evaluated once per pixel at the visible surface (14 fetches), compiled out when off.
    #[arg(long, value_enum, hide_short_help = true)]
    pub depth_cues: Option<Switch>,
    /// Strengths 0..1 of the occlusion, the shadow and the outlines [default: 0.6,0.4,0.5]
    #[arg(long, value_name = "OCCLUSION,SHADOW,OUTLINE", value_parser = parse_cue_strengths, hide_short_help = true)]
    pub cue_strength: Option<[f32; 3]>,
    /// Where the gradient term comes from.
    #[arg(long, value_enum, default_value_t = GradientArg::Precomputed, hide_short_help = true)]
    pub gradient: GradientArg,
    /// Precision of the stored derived volumes.
    ///
    /// For diagnosis-quality stills use `--step 0.125 --derived-precision f16` (ACCURACY.md).
    #[arg(long, value_enum, default_value_t = PrecisionArg::Snorm8)]
    pub derived_precision: PrecisionArg,
    /// How the tissue windows are evaluated per sample.
    ///
    /// `table` (the default) replaces the per-sample window arithmetic by one lookup in a
    /// 4096-entry transfer-function table (at most 1.1e-4 of a window's weight at a 0.01 edge;
    /// the accuracy study finds no difference at its precision); `exact` evaluates every window
    /// per sample, as the paper's eq. 4 is written.
    #[arg(long, value_enum, default_value_t = ClassificationArg::Table, hide_short_help = true)]
    pub classification: ClassificationArg,
    /// Background colour as #RRGGBB or R,G,B in 0..255.
    #[arg(long, default_value = "#000000", value_parser = parse_colour)]
    pub background: [f32; 3],
    /// Disable the per-pixel jitter of ray starts (shows wood-grain banding; for comparisons).
    #[arg(long, hide_short_help = true)]
    pub no_jitter: bool,
    /// A tissue's window by hand, in I_norm (0..1): TISSUE=LO:HI, repeatable
    ///
    /// `morphray peaks` shows where the modes are (`--window wm=0.7:0.95 --window gm=0.5:0.7`).
    /// Replaces the adaptive or paper window of that tissue; the viewer's bands do the same.
    /// `vessels=LO:HI` sets the vessel channel's window, on the vesselness (0..1).
    #[arg(long = "window", value_name = "TISSUE=LO:HI", value_parser = parse_window)]
    pub window: Vec<(Channel, f64, f64)>,
    /// A tissue's opacity per mm of ray, 0..1: TISSUE=X, repeatable.
    ///
    /// `--opacity csf=0.1`; `head` and `vessels` take one too.
    #[arg(long = "opacity", visible_alias = "tissue-opacity", value_name = "TISSUE=X", value_parser = parse_opacity)]
    pub opacity: Vec<(Channel, f32)>,
    /// A tissue's colour: TISSUE=#RRGGBB or TISSUE=R,G,B (0..255), repeatable
    ///
    /// `--color wm=#f0f0e0` gives white matter an off-white.
    #[arg(long = "color", visible_alias = "tissue-color", value_name = "TISSUE=#RRGGBB", value_parser = parse_tissue_colour)]
    pub color: Vec<(Channel, [f32; 3])>,
    /// Crop, clip planes and colour map (src/cli/clip.rs).
    #[command(flatten)]
    pub clip: super::clip::ClipArgs,
    /// A standard view (src/cli/view_preset.rs).
    #[command(flatten)]
    pub view: super::view_preset::ViewPresetArgs,
    /// Denoise I_norm first: none, gaussian:SIGMA_MM, median or bilateral:SIGMA_MM,RANGE
    ///
    /// The derivatives and the raymarch read the filtered volume. Whole volumes only: a bricked
    /// one is refused.
    #[arg(long, default_value = "none", value_parser = parse_denoise)]
    pub denoise: crate::passes::denoise::Denoise,
}

impl SceneArgs {
    /// These arguments for a still (`render`, `view`'s first view, Python's `render()`): the
    /// look of `scene::lighting::still_effects` (shaded, studio lighting, depth cues) where the
    /// arguments say nothing.
    /// `--preset paper` keeps the paper's look: the headlight without cues.
    pub fn as_still(&self) -> SceneArgs {
        let paper =
            super::preset_arg::PresetArg::preset(self.preset) == Some(crate::scene::Preset::Paper);
        let still = crate::scene::lighting::still_effects(crate::scene::Effects::default());
        let (lighting, cues) = if paper {
            (LightingArg::Headlight, Switch::Off)
        } else {
            let model = match still.lighting.model {
                crate::scene::LightModel::Studio => LightingArg::Studio,
                crate::scene::LightModel::Headlight => LightingArg::Headlight,
                crate::scene::LightModel::Matcap => LightingArg::Matcap,
            };
            (model, Switch::from(still.lighting.depth_cues))
        };
        SceneArgs {
            shading: Some(self.shading.unwrap_or(Switch::from(still.shading))),
            lighting: Some(self.light_model_arg().unwrap_or(lighting)),
            depth_cues: Some(self.depth_cues.unwrap_or(cues)),
            ..self.clone()
        }
    }

    /// The lighting asked for: `--lighting`, or the matcap model when only `--matcap` is given.
    pub fn light_model_arg(&self) -> Option<LightingArg> {
        self.lighting
            .or(self.matcap.as_ref().map(|_| LightingArg::Matcap))
    }

    /// The matcap `--matcap` names, loaded (None without the option).
    pub fn matcap_image(
        &self,
    ) -> Result<Option<crate::scene::matcap::MatcapImage>, crate::error::Error> {
        self.matcap
            .as_deref()
            .map(crate::scene::matcap::MatcapImage::load)
            .transpose()
            .map_err(|e| crate::error::Error::Usage(e.to_string()))
    }

    /// The outline and depth-cue strengths (`--cue-strength`), the library's defaults otherwise.
    pub fn cues(&self) -> crate::scene::DepthCues {
        let mut cues = crate::scene::DepthCues::default();
        if let Some([occlusion, shadow, outline]) = self.cue_strength {
            cues.occlusion = occlusion;
            cues.shadow = shadow;
            cues.silhouette = outline;
        }
        cues
    }
}

fn parse_brain(text: &str) -> Result<crate::passes::brain::BrainSwitch, String> {
    crate::passes::brain::BrainSwitch::parse(text)
        .ok_or_else(|| format!("--brain `{text}`: use auto, on or off"))
}

fn parse_cue_strengths(text: &str) -> Result<[f32; 3], String> {
    let values: Vec<f32> = text
        .split(',')
        .map(|v| {
            v.trim()
                .parse::<f32>()
                .ok()
                .filter(|x| (0.0..=1.0).contains(x))
        })
        .collect::<Option<_>>()
        .ok_or_else(|| format!("`{text}`: expected three strengths in 0..1"))?;
    <[f32; 3]>::try_from(values)
        .map_err(|_| format!("`{text}`: expected OCCLUSION,SHADOW,OUTLINE, e.g. 0.6,0.4,0.5"))
}

fn parse_denoise(text: &str) -> Result<crate::passes::denoise::Denoise, String> {
    text.parse()
}

/// What `--window`, `--opacity` and `--color` set: a tissue, or the vessel channel (`vessels`,
/// whose window is on the vesselness 0..1 rather than I_norm).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// One of the four tissue classes.
    Tissue(TissueClass),
    /// The vessel channel.
    Vessels,
    /// The head layer around an extracted brain.
    Head,
}

impl serde::Serialize for Channel {
    /// As on the command line (`wm`, `vessels`), so a picture's recorded arguments read as typed.
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            Channel::Tissue(t) => serializer.serialize_str(t.name()),
            Channel::Vessels => serializer.serialize_str("vessels"),
            Channel::Head => serializer.serialize_str("head"),
        }
    }
}

/// `TISSUE=REST` split, with the tissue (or `vessels`) named as on the command line.
fn tissue_and(text: &str) -> Result<(Channel, &str), String> {
    let (name, rest) = text
        .split_once('=')
        .ok_or_else(|| format!("`{text}`: expected TISSUE=VALUE, e.g. wm=0.7:0.95"))?;
    if name.trim().eq_ignore_ascii_case("vessels") {
        return Ok((Channel::Vessels, rest));
    }
    if name.trim().eq_ignore_ascii_case("head") {
        return Ok((Channel::Head, rest));
    }
    let tissue = TissueClass::parse(name).ok_or_else(|| {
        format!("unknown tissue `{name}`; use csf, gm, wm, pathology, vessels or head")
    })?;
    Ok((Channel::Tissue(tissue), rest))
}

fn parse_window(text: &str) -> Result<(Channel, f64, f64), String> {
    let (tissue, rest) = tissue_and(text)?;
    let (lo, hi) = rest
        .split_once(':')
        .ok_or_else(|| format!("`{rest}`: expected LO:HI in I_norm units, e.g. 0.7:0.95"))?;
    let number = |v: &str| {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("`{v}` is not a finite number"))
    };
    let (lo, hi) = (number(lo)?, number(hi)?);
    if !((0.0..=1.0).contains(&lo) && lo < hi && hi <= 1.5) {
        return Err(format!(
            "window {lo}:{hi}: needs 0 <= LO < HI (I_norm runs from 0 to 1; HI may pass 1 to \
             include the brightest voxels)"
        ));
    }
    Ok((tissue, lo, hi))
}

fn parse_opacity(text: &str) -> Result<(Channel, f32), String> {
    let (tissue, rest) = tissue_and(text)?;
    let x: f32 = rest
        .trim()
        .parse()
        .map_err(|_| format!("`{rest}` is not a number"))?;
    if !(0.0..=1.0).contains(&x) {
        return Err(format!("opacity {x} must lie in 0..1"));
    }
    Ok((tissue, x))
}

fn parse_tissue_colour(text: &str) -> Result<(Channel, [f32; 3]), String> {
    let (tissue, rest) = tissue_and(text)?;
    Ok((tissue, parse_colour(rest)?))
}
