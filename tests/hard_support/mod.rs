//! Helpers shared by the hard-case tests (tests/hard_cases*.rs): rendering into RGBA32F, the f64
//! reference render of the same inputs, image comparison, and the "x-ramp" construction whose
//! opacity per millimetre is known exactly.
#![allow(dead_code)]

use ash::vk;
use morphray::engine::readback::read_image;
use morphray::engine::{Derived, Engine, PreparedVolume};
use morphray::gpu::Access;
use morphray::passes::derivatives::DerivativeOutputs;
use morphray::reference::raymarch::{ReferenceDerived, ReferenceRaymarch, ReferenceVolume};
use morphray::scene::uniforms::GradientStats;
use morphray::scene::{
    Camera, Classification, Effects, Projection, Scene, TissueClass, VolumeGeometry, Window,
};
use morphray::volume::{AffineSource, LinearMap, Orientation, Samples, Volume};

/// Every derived output.
pub const ALL_OUTPUTS: DerivativeOutputs = DerivativeOutputs {
    magnitude: true,
    curvature: true,
    normal: true,
    precision: morphray::scene::DerivedPrecision::F16,
    vesselness: false,
    brain: morphray::passes::brain::BrainSwitch::Off,
};

/// A volume on a diagonal affine with the given spacing (mm) and origin at voxel (0, 0, 0).
pub fn volume(dims: [usize; 3], spacing: [f64; 3], samples: Samples) -> Volume {
    Volume {
        name: "hard case".into(),
        dims,
        spacing_mm: spacing.map(f64::abs),
        orientation: Orientation::from_spacing(spacing, AffineSource::Synthetic),
        samples,
        to_physical: LinearMap::IDENTITY,
        warnings: vec![],
        facts: Default::default(),
    }
}

/// A volume with a full row-major affine.
pub fn volume_with_affine(dims: [usize; 3], affine: [[f64; 4]; 4], samples: Samples) -> Volume {
    let mut v = volume(dims, [1.0; 3], samples);
    for (axis, spacing) in v.spacing_mm.iter_mut().enumerate() {
        *spacing = (0..3)
            .map(|r| affine[r][axis] * affine[r][axis])
            .sum::<f64>()
            .sqrt();
    }
    v.orientation = Orientation {
        affine,
        source: AffineSource::Synthetic,
    };
    v
}

/// Renders into an RGBA32F target and returns the pixels (rows top to bottom).
pub fn render(
    engine: &mut Engine,
    prepared: &PreparedVolume,
    derived: Option<&Derived>,
    scene: &Scene,
    w: u32,
    h: u32,
) -> Vec<[f64; 4]> {
    let mut target = engine
        .render_target(w, h, vk::Format::R32G32B32A32_SFLOAT)
        .unwrap();
    let frame = engine
        .render(&mut target, prepared, derived, scene)
        .unwrap();
    assert_eq!(frame.values.len(), (w * h * 4) as usize);
    frame
        .values
        .chunks_exact(4)
        .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64])
        .collect()
}

/// I_norm as the GPU stored it.
pub fn normalized(engine: &Engine, prepared: &PreparedVolume) -> Vec<f32> {
    read_image(
        engine.device(),
        &prepared.normalized,
        Access::ComputeSampled,
    )
    .unwrap()
    .values
}

/// (|g|, k) per voxel and the normals (xyz) as the derivative pass stored them; None for what
/// was not computed.
pub struct DerivedData {
    pub magnitude: Vec<f64>,
    pub curvature: Option<Vec<f64>>,
    pub normals: Option<Vec<[f64; 3]>>,
}

pub fn derived_data(engine: &Engine, derived: &Derived) -> DerivedData {
    let device = engine.device();
    let (mut magnitude, mut curvature) = (Vec::new(), Vec::new());
    let mut has_curvature = false;
    if let Some(g) = &derived.volumes.gradient {
        let g = read_image(device, g, Access::ComputeSampled).unwrap();
        has_curvature = g.channels > 1;
        // Stored in voxel units (|g| h, k h^2); back to world units.
        let [sg, sk] = derived.volumes.store_scale.map(f64::from);
        for texel in g.values.chunks_exact(g.channels) {
            magnitude.push(texel[0] as f64 / sg);
            if has_curvature {
                curvature.push(texel[1] as f64 / sk);
            }
        }
    }
    let normals = derived.volumes.normal.as_ref().map(|n| {
        read_image(device, n, Access::ComputeSampled)
            .unwrap()
            .values
            .chunks_exact(4)
            .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64])
            .collect()
    });
    DerivedData {
        magnitude,
        curvature: has_curvature.then_some(curvature),
        normals,
    }
}

/// The f64 reference render of `scene` on the GPU's own I_norm and derived volumes (so only the
/// raymarch is under test).
pub fn reference(
    engine: &Engine,
    prepared: &PreparedVolume,
    derived: Option<&Derived>,
    scene: &Scene,
    w: u32,
    h: u32,
) -> Vec<[f64; 4]> {
    with_twin(engine, prepared, derived, scene, [w, h], |twin| {
        twin.render()
    })
}

/// `use_twin` of the f64 twin of the raymarch of `scene` at `size`, on the GPU's own I_norm and
/// derived volumes, lit by the engine's matcap (the engine's state, not the scene's).
pub fn with_twin<T>(
    engine: &Engine,
    prepared: &PreparedVolume,
    derived: Option<&Derived>,
    scene: &Scene,
    size: [u32; 2],
    use_twin: impl FnOnce(&ReferenceRaymarch<'_>) -> T,
) -> T {
    let norm: Vec<f64> = normalized(engine, prepared)
        .iter()
        .map(|&v| v as f64)
        .collect();
    let geometry = VolumeGeometry::new(prepared.dims, prepared.affine).unwrap();
    let volume = ReferenceVolume::new(prepared.dims, &norm).unwrap();
    let mut stats = GradientStats {
        max_magnitude: 0.0,
        tau: 0.0,
    };
    let data = derived.map(|d| {
        stats = d.stats;
        derived_data(engine, d)
    });
    let refs = match &data {
        Some(d) => ReferenceDerived {
            gradient_magnitude: (!d.magnitude.is_empty()).then_some(d.magnitude.as_slice()),
            curvature: d.curvature.as_deref(),
            normals: d.normals.as_deref(),
        },
        None => ReferenceDerived::NONE,
    };
    let twin = ReferenceRaymarch::new(scene, &geometry, &stats, &volume, &refs, size[0], size[1])
        .unwrap()
        .with_matcap(std::sync::Arc::new(engine.matcap().clone()));
    use_twin(&twin)
}

/// (PSNR over RGB with peak 1, 99th-percentile abs error, max abs error) over the pixels `mask`
/// selects (all when None).
pub fn compare(a: &[[f64; 4]], b: &[[f64; 4]], mask: Option<&[bool]>) -> (f64, f64, f64) {
    let mut errors: Vec<f64> = a
        .iter()
        .zip(b)
        .enumerate()
        .filter(|(i, _)| mask.is_none_or(|m| m[*i]))
        .flat_map(|(_, (x, y))| (0..3).map(move |c| (x[c] - y[c]).abs()))
        .collect();
    assert!(!errors.is_empty(), "no pixel selected");
    let mse = errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64;
    errors.sort_by(f64::total_cmp);
    let p99 = errors[(errors.len() * 99) / 100];
    let max = *errors.last().unwrap();
    (10.0 * (1.0 / mse.max(1e-20)).log10(), p99, max)
}

/// Asserts every channel of every pixel is finite and in [0, hi].
pub fn assert_finite_in_range(label: &str, image: &[[f64; 4]], hi: f64) {
    for (i, px) in image.iter().enumerate() {
        assert!(
            px.iter().all(|v| v.is_finite() && (0.0..=hi).contains(v)),
            "{label}: pixel {i} = {px:?}"
        );
    }
}

/// A window whose smooth edges lie outside [0, 1]: weight exactly 1 for every I_norm.
pub const EVERYTHING: Window = Window {
    lo: -0.5,
    hi: 1.5,
    edge: 0.01,
};

/// The "x-ramp": I = i (u16) on `dims` with dims[0] = 4, so I_norm = i / 3 is exact in R16
/// (65535 = 3 x 21845) and the derivative pass stores one constant |g| = 1 / (3 spacing_x) per
/// mm everywhere (one-sided differences at the borders are exact on a ramp). With a window of
/// weight 1 over [0, 1] and max |g| set to that stored value, every sample has opacity exactly
/// the tissue's opacity per millimetre: a homogeneous medium of extinction
/// tau = -ln(1 - opacity) per mm whatever its grid.
pub struct XRamp {
    pub prepared: PreparedVolume,
    pub derived: Derived,
    pub scene: Scene,
}

pub fn x_ramp(engine: &mut Engine, dims: [usize; 3], spacing: [f64; 3], opacity: f32) -> XRamp {
    assert_eq!(
        dims[0], 4,
        "I_norm = i / 3 is exact in R16 only for 4 columns"
    );
    let values: Vec<u16> = (0..dims.iter().product::<usize>())
        .map(|i| (i % 4) as u16)
        .collect();
    let v = volume(dims, spacing, Samples::from_u16(&values));
    let prepared = engine.prepare(&v).unwrap();
    let mut derived = engine
        .derive(
            &prepared,
            DerivativeOutputs {
                magnitude: true,
                ..Default::default()
            },
        )
        .unwrap();
    let stored = derived_data(engine, &derived).magnitude;
    let first = stored[0];
    assert!(
        stored.iter().all(|&m| m == first) && first > 0.0,
        "the ramp's stored |g| is one constant"
    );
    // max |g| as the raymarch will read it (the f16 value), so |g| / max|g| = 1 to one f32 ulp.
    derived.stats.max_magnitude = first;
    let mut classification = Classification::with_windows([Some(EVERYTHING), None, None, None]);
    classification.show_only(&[TissueClass::Csf]);
    let style = classification.style_mut(TissueClass::Csf);
    style.colour = [1.0, 1.0, 1.0];
    style.opacity = opacity;
    let mut scene = Scene::new(classification);
    scene.effects = Effects::default();
    scene.jitter = false;
    scene.background = [0.0, 0.0, 0.0];
    XRamp {
        prepared,
        derived,
        scene,
    }
}

/// An orthographic camera looking along -y (azimuth 0, elevation 0: forward is exactly
/// (0, -1, 0) in f64 and f32), zoomed so the image spans `half_mm` either side of the box centre.
pub fn orthographic_along_y(prepared: &PreparedVolume, half_mm: f64) -> Camera {
    let geometry = VolumeGeometry::new(prepared.dims, prepared.affine).unwrap();
    let (lo, hi) = geometry.world_bounds();
    let radius = (hi - lo).max_element() * 0.5;
    Camera {
        azimuth_deg: 0.0,
        elevation_deg: 0.0,
        zoom: radius / half_mm,
        pan_mm: [0.0, 0.0],
        projection: Projection::Orthographic,
    }
}

/// `prepare` of `v` beside the CPU's view of the same samples: which voxels are finite, how many,
/// the finite range, and the GPU's I_norm read back.
pub struct CheckedPrepare {
    pub prepared: PreparedVolume,
    pub finite: Vec<bool>,
    pub finite_count: usize,
    pub cpu_range: Option<(f64, f64)>,
    pub norm: Vec<f32>,
}

/// Prepares `v` and asserts the one promise every hard-case check starts from: the stored range
/// is the finite range of the samples, bit for bit (NaN and +-Inf excluded by bit tests).
pub fn prepare_checked(label: &str, engine: &mut Engine, v: &Volume) -> CheckedPrepare {
    let prepared = engine.prepare(v).unwrap();
    let n = v.voxel_count();
    let finite: Vec<bool> = (0..n).map(|i| v.samples.get(i).is_finite()).collect();
    let finite_count = finite.iter().filter(|&&f| f).count();
    let cpu_range = morphray::reference::minmax::finite_min_max(&v.samples);
    assert_eq!(
        prepared
            .stored_range
            .map(|(a, b)| (a.to_bits(), b.to_bits())),
        cpu_range.map(|(a, b)| (a.to_bits(), b.to_bits())),
        "{label}: stored range"
    );
    let norm = normalized(engine, &prepared);
    CheckedPrepare {
        prepared,
        finite,
        finite_count,
        cpu_range,
        norm,
    }
}
