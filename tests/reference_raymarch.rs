//! Acceptance properties of the f64 reference raymarch (`morphray::reference::raymarch`), run on
//! the reference itself: the GPU image is later compared against this reference, so the
//! reference must first be shown to have the properties the issue asks of a raymarch.
//!
//! Every tolerance is stated where it is used, with the reason it holds.

use glam::{DVec3, DVec4};
use morphray::reference::raymarch::{
    ReferenceDerived, ReferenceRaymarch, ReferenceVolume, jitter, render,
};
use morphray::scene::uniforms::GradientStats;
use morphray::scene::{
    Camera, Classification, Effects, GradientSource, Projection, RenderMode, Scene, TissueClass,
    VolumeGeometry, Window,
};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Helpers

/// Row-major affine with the given (signed) spacing and world position of voxel (0, 0, 0).
fn diagonal_affine(spacing: [f64; 3], origin: [f64; 3]) -> [[f64; 4]; 4] {
    [
        [spacing[0], 0.0, 0.0, origin[0]],
        [0.0, spacing[1], 0.0, origin[1]],
        [0.0, 0.0, spacing[2], origin[2]],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

fn identity_geometry(dims: [u32; 3]) -> VolumeGeometry {
    VolumeGeometry::new(dims, diagonal_affine([1.0; 3], [0.0; 3])).unwrap()
}

/// Geometry whose sampled box `[-0.5, dim - 0.5]` is the world box `[0, extent]^3` mm, with the
/// given signed spacing (a negative spacing flips that axis: voxel 0 sits at the high end).
fn box_geometry(spacing: [f64; 3], extent: f64) -> VolumeGeometry {
    let dims = spacing.map(|s| (extent / s.abs()).round() as u32);
    let origin = spacing.map(|s| if s > 0.0 { s / 2.0 } else { extent + s / 2.0 });
    VolumeGeometry::new(dims, diagonal_affine(spacing, origin)).unwrap()
}

fn voxel_world(g: &VolumeGeometry, i: u32, j: u32, k: u32) -> DVec3 {
    (g.index_to_world * DVec4::new(f64::from(i), f64::from(j), f64::from(k), 1.0)).truncate()
}

/// Samples a world-space function at every voxel centre (x fastest).
fn sample_world(g: &VolumeGeometry, f: impl Fn(DVec3) -> f64) -> Vec<f64> {
    let [nx, ny, nz] = g.dims;
    let mut v = Vec::with_capacity((nx * ny * nz) as usize);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                v.push(f(voxel_world(g, i, j, k)));
            }
        }
    }
    v
}

/// Deterministic noise in [0, 1) (splitmix64).
struct Noise(u64);

impl Noise {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn window(lo: f64, hi: f64, edge: f64) -> Option<Window> {
    Some(Window { lo, hi, edge })
}

fn orthographic_anterior() -> Camera {
    Camera {
        projection: Projection::Orthographic,
        ..Camera::default()
    }
}

fn background_of(scene: &Scene) -> [f64; 4] {
    let b = scene.background.map(f64::from);
    [b[0], b[1], b[2], 1.0]
}

fn max_abs_diff(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn all_effect_combinations() -> Vec<Effects> {
    let mut out = Vec::new();
    for gradient_source in [GradientSource::Precomputed, GradientSource::OnTheFly] {
        for curvature in [false, true] {
            for shading in [false, true] {
                out.push(Effects {
                    mode: RenderMode::Dvr,
                    curvature,
                    shading,
                    gradient_source,
                    quality: Default::default(),
                    vessels: false,
                    brain: morphray::passes::brain::BrainSwitch::Off,
                    lighting: Default::default(),
                });
            }
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Transparency

#[test]
fn fully_transparent_scene_is_exactly_the_background() {
    let dims = [20, 22, 18];
    let g = VolumeGeometry::new(
        dims,
        [
            [0.9, 0.2, 0.0, -5.0],
            [-0.1, 1.1, 0.3, 2.0],
            [0.0, -0.2, 1.4, 1.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
    )
    .unwrap();
    let mut noise = Noise(7);
    let norm: Vec<f64> = (0..20 * 22 * 18).map(|_| noise.next()).collect();
    let magnitude: Vec<f64> = norm.iter().map(|v| 0.1 * v).collect();
    let curvature: Vec<f64> = norm.iter().map(|v| v - 0.5).collect();
    let normals: Vec<[f64; 3]> = norm.iter().map(|&v| [v, 1.0 - v, 0.5]).collect();
    let derived = ReferenceDerived {
        gradient_magnitude: Some(&magnitude),
        curvature: Some(&curvature),
        normals: Some(&normals),
    };
    let volume = ReferenceVolume::new(dims, &norm).unwrap();
    let stats = GradientStats {
        max_magnitude: 0.1,
        tau: 1e-4,
    };
    let classification = Classification::with_windows([
        window(0.0, 0.3, 0.05),
        window(0.3, 0.6, 0.05),
        window(0.6, 0.9, 0.05),
        window(0.9, 1.0, 0.05),
    ]);
    let mut scene = Scene::new(classification);
    scene.background = [0.25, 0.5, 0.125];
    scene.camera.zoom = 1.5;
    for effects in all_effect_combinations() {
        scene.effects = effects;
        // The same scene with the tissues shown is visible somewhere, so "background
        // everywhere" below is a property of hiding them, not of an empty picture.
        scene.classification = classification;
        scene.classification.show_only(&TissueClass::ALL);
        let shown = render(&scene, &g, &stats, &volume, &derived, 24, 20).unwrap();
        assert!(
            shown.iter().any(|p| p != &background_of(&scene)),
            "{effects:?}"
        );
        // Hidden: every sample has f = 0 and is skipped, A = 0 and C = 0, so the result is
        // 0 + (1 - 0) * background: exactly the background (tolerance 0).
        scene.classification.show_only(&[]);
        let hidden = render(&scene, &g, &stats, &volume, &derived, 24, 20).unwrap();
        assert_eq!(hidden.len(), 24 * 20);
        assert!(
            hidden.iter().all(|p| p == &background_of(&scene)),
            "{effects:?}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Homogeneous slab: opacity correction, step-size and jitter invariance

/// A volume of constant I_norm 0.5 fully inside one tissue window (weight exactly 1) and a
/// precomputed |g| equal to max|g| everywhere, so every sample has a = f = the tissue opacity.
struct Slab {
    geometry: VolumeGeometry,
    norm: Vec<f64>,
    magnitude: Vec<f64>,
    scene: Scene,
    alpha: f64,
    colour: [f64; 3],
}

fn slab(geometry: VolumeGeometry) -> Slab {
    let n = geometry.dims.iter().map(|&d| d as usize).product();
    let mut classification =
        Classification::with_windows([window(0.2, 0.8, 0.05), None, None, None]);
    let style = classification.style_mut(TissueClass::Csf);
    style.opacity = 0.05;
    style.colour = [1.0, 0.5, 0.25];
    let alpha = f64::from(style.opacity);
    let colour = style.colour.map(f64::from);
    let mut scene = Scene::new(classification);
    scene.background = [0.0, 0.0, 1.0];
    // Early termination off: A stays below 0.9 here anyway, and the closed form below
    // assumes every sample is composited.
    scene.early_termination = 1.0;
    Slab {
        geometry,
        norm: vec![0.5; n],
        magnitude: vec![1.0; n],
        scene,
        alpha,
        colour,
    }
}

const UNIT_MAX: GradientStats = GradientStats {
    max_magnitude: 1.0,
    tau: 1e-6,
};

impl Slab {
    fn raymarch(&self, width: u32, height: u32) -> ReferenceRaymarch<'_> {
        let volume = ReferenceVolume::new(self.geometry.dims, &self.norm).unwrap();
        let derived = ReferenceDerived {
            gradient_magnitude: Some(&self.magnitude),
            ..ReferenceDerived::NONE
        };
        ReferenceRaymarch::new(
            &self.scene,
            &self.geometry,
            &UNIT_MAX,
            &volume,
            &derived,
            width,
            height,
        )
        .unwrap()
    }

    /// Extinction per mm: one voxel length (voxel_mm) absorbs alpha, so
    /// 1 - alpha = exp(-tau voxel_mm).
    fn tau(&self) -> f64 {
        // Opacities are per millimetre of ray (scene::REFERENCE_LENGTH_MM).
        -(1.0 - self.alpha).ln() / morphray::scene::REFERENCE_LENGTH_MM
    }

    /// The pixel of accumulated opacity A over a constant colour: A C_s + (1 - A) background.
    fn expected(&self, opacity: f64) -> [f64; 4] {
        let b = self.scene.background.map(f64::from);
        let c = self.colour;
        [
            opacity * c[0] + (1.0 - opacity) * b[0],
            opacity * c[1] + (1.0 - opacity) * b[1],
            opacity * c[2] + (1.0 - opacity) * b[2],
            1.0,
        ]
    }
}

#[test]
fn homogeneous_slab_matches_beer_lambert_at_every_step_and_jitter() {
    // Orthographic view along -y through a 1 mm grid 40 voxels deep: every ray that hits has
    // a chord of L = 40 mm, a multiple of every step (0.25, 0.5, 1 mm).
    let mut s = slab(identity_geometry([10, 40, 10]));
    s.scene.camera = orthographic_anterior();
    let length = 40.0;
    // Each sample absorbs 1 - (1 - alpha)^r (r = dt / voxel_mm); n samples absorb
    // 1 - (1 - alpha)^(r n) = 1 - exp(-tau n dt). With start offset u in (0, 1) the sample count
    // is floor(L/dt - u) + 1 = L/dt, so n dt = L and A = 1 - exp(-tau L) exactly, for every step
    // and every jitter offset. What remains is f64 rounding over <= 160 samples: < 1e-13; the
    // bound 1e-12 leaves margin and is still ~1e10 times smaller than the effect of a wrong
    // correction exponent.
    let exact = 1.0 - (-s.tau() * length).exp();
    assert!(
        (exact - (1.0 - 0.95f64.powi(40))).abs() < 1e-7,
        "alpha is the f32 0.05"
    );
    let expected = s.expected(exact);
    let mut hits = 0;
    let mut offsets = Vec::new();
    for jitter_on in [false, true] {
        for step in [0.25, 0.5, 1.0] {
            s.scene.jitter = jitter_on;
            s.scene.step_voxels = step;
            let r = s.raymarch(15, 15);
            for y in 0..15 {
                for x in 0..15 {
                    let plan = r.ray(x, y);
                    let pixel = r.pixel(x, y);
                    let Some((t_near, t_far)) = plan.hit else {
                        assert_eq!(pixel, background_of(&s.scene));
                        continue;
                    };
                    hits += 1;
                    assert!((t_far - t_near - length).abs() < 1e-9);
                    assert_eq!(plan.count, (length / step) as u32, "n dt = L");
                    let err = max_abs_diff(&pixel, &expected);
                    assert!(err < 1e-12, "step {step} jitter {jitter_on}: {err:e}");
                    if jitter_on {
                        offsets.push(plan.offset);
                    } else {
                        assert_eq!(plan.offset, 0.5);
                    }
                }
            }
        }
    }
    assert!(hits >= 6 * 9, "the view must cover the slab: {hits} hits");
    // Jitter moved the samples (different start offsets across pixels, none at the unjittered
    // 0.5), yet the result above did not change beyond the bound.
    assert!(offsets.iter().all(|&o| (0.0..1.0).contains(&o) && o != 0.5));
    let first = offsets[0];
    assert!(offsets.iter().any(|&o| (o - first).abs() > 0.1));
}

/// World-space slab test against an axis-aligned world box (independent of the engine's
/// index-space intersection), for the chord length in mm.
fn world_chord(origin: DVec3, direction: DVec3, lo: DVec3, hi: DVec3) -> Option<f64> {
    let mut t0 = f64::NEG_INFINITY;
    let mut t1 = f64::INFINITY;
    for a in 0..3 {
        let (l, h) = (
            (lo[a] - origin[a]) / direction[a],
            (hi[a] - origin[a]) / direction[a],
        );
        t0 = t0.max(l.min(h));
        t1 = t1.min(l.max(h));
    }
    (t0 < t1 && t1 > 0.0).then(|| t1 - t0.max(0.0))
}

#[test]
fn oblique_rays_through_an_anisotropic_slab_follow_beer_lambert_within_one_step() {
    // Perspective, oblique view of a 2 x 1.5 x 3 mm grid: chords are no longer multiples of the
    // step. The parameter is in mm, so the chord must equal an independent world-space chord;
    // one voxel of step and of opacity is the finest axis, 1.5 mm.
    let mut s = slab(box_geometry([2.0, 1.5, 3.0], 24.0));
    assert_eq!(s.geometry.voxel_mm, 1.5);
    s.scene.camera = Camera {
        azimuth_deg: 33.0,
        elevation_deg: 21.0,
        zoom: 1.4,
        ..Camera::default()
    };
    let (lo, hi) = s.geometry.world_bounds();
    let tau = s.tau();
    let mut results: Vec<Vec<Option<f64>>> = Vec::new();
    for step in [0.25, 0.5, 1.0] {
        s.scene.step_voxels = step;
        let mut opacities = Vec::new();
        for jitter_on in [false, true] {
            s.scene.jitter = jitter_on;
            let r = s.raymarch(20, 20);
            let rays = *r.camera_rays();
            for y in 0..20 {
                for x in 0..20 {
                    let plan = r.ray(x, y);
                    let pixel = r.pixel(x, y);
                    let (o, d) = rays.ray(f64::from(x), f64::from(y), 20, 20);
                    let Some(length) = world_chord(o, d, lo, hi) else {
                        assert!(plan.count == 0 && pixel == background_of(&s.scene));
                        if !jitter_on {
                            opacities.push(None);
                        }
                        continue;
                    };
                    let (t_near, t_far) = plan.hit.unwrap();
                    // Same chord in index space (parameter in mm) and in world space: both are
                    // a few f64 operations on ~100 mm quantities, 1e-9 mm is generous.
                    assert!((t_far - t_near - length).abs() < 1e-9);
                    let dt = plan.step_mm;
                    assert_eq!(dt, step * 1.5);
                    let n = f64::from(plan.count);
                    // Discrete identity, to rounding (1e-12, as in the axis-aligned test):
                    // n samples of 1 - (1 - alpha)^r give A = 1 - exp(-tau n dt).
                    let discrete = 1.0 - (-tau * n * dt).exp();
                    let err = max_abs_diff(&pixel, &s.expected(discrete));
                    assert!(err < 1e-12, "step {step}: {err:e}");
                    // n = floor(L/dt - u) + 1 puts n dt in (L - u dt, L + (1 - u) dt]: within
                    // dt/2 of L without jitter (u = 1/2) and within dt with it. Since
                    // |d/dL exp(-tau L)| <= tau, A is within tau * dt / 2 (resp. tau * dt) of
                    // the continuous 1 - exp(-tau L).
                    let bound = if jitter_on { tau * dt } else { tau * dt / 2.0 };
                    let continuous = 1.0 - (-tau * length).exp();
                    assert!((pixel[0] - continuous).abs() <= bound + 1e-12);
                    if !jitter_on {
                        opacities.push(Some(pixel[0]));
                    }
                }
            }
        }
        results.push(opacities);
    }
    // Step-size invariance: without jitter each step is within tau dt / 2 of the continuous
    // value, so two steps agree within tau (dt1 + dt2) / 2 (dt = 1.5 mm * step in voxels).
    let steps = [0.25, 0.5, 1.0].map(|s| s * 1.5);
    let mut compared = 0;
    for a in 0..3 {
        for b in a + 1..3 {
            let bound = tau * (steps[a] + steps[b]) / 2.0 + 1e-12;
            for (pa, pb) in results[a].iter().zip(&results[b]) {
                if let (Some(pa), Some(pb)) = (pa, pb) {
                    assert!((pa - pb).abs() <= bound, "{pa} vs {pb} > {bound}");
                    compared += 1;
                }
            }
        }
    }
    assert!(compared > 3 * 100, "only {compared} comparisons");
}

// ---------------------------------------------------------------------------------------------
// Jitter

#[test]
fn jitter_is_deterministic_in_unit_interval_and_well_spread() {
    let mut sum = 0.0;
    let mut distinct = std::collections::BTreeSet::new();
    let mut below_half = 0;
    for y in 0..64 {
        for x in 0..64 {
            let j = jitter(x, y, 3);
            assert!((0.0..1.0).contains(&j));
            // A multiple of 2^-24: the f32 value of the shader, exactly.
            assert_eq!((j * 16_777_216.0).fract(), 0.0);
            assert_eq!(j, jitter(x, y, 3), "deterministic");
            sum += j;
            below_half += usize::from(j < 0.5);
            distinct.insert((j * 16_777_216.0) as u32);
        }
    }
    // 4096 values from a 24-bit hash: collisions are rare (expected ~0.5).
    assert!(distinct.len() >= 4090);
    // A deterministic pattern, so these are exact checks of one fixed set of numbers; the
    // margins (5 sigma of a uniform sample: 0.5 +- 0.0225, 2048 +- 160) only document that the
    // values are spread over [0, 1) rather than clumped.
    let mean = sum / 4096.0;
    assert!((mean - 0.5).abs() < 0.0225, "{mean}");
    assert!((below_half as i64 - 2048).abs() < 160, "{below_half}");
    // The frame changes the pattern.
    let changed = (0..64)
        .filter(|&x| jitter(x, 0, 3) != jitter(x, 0, 4))
        .count();
    assert_eq!(changed, 64);
}

// ---------------------------------------------------------------------------------------------
// Hard geometry: camera inside, rays on faces, grazing rays

/// A linear ramp over the whole box, inside one window: every sample is visible with a
/// non-zero on-the-fly gradient.
fn ramp_setup(dims: [u32; 3]) -> (VolumeGeometry, Vec<f64>, GradientStats, Scene) {
    let g = identity_geometry(dims);
    let grad = DVec3::new(0.01, 0.013, 0.017);
    let norm = sample_world(&g, |x| 0.2 + grad.dot(x));
    let stats = GradientStats {
        max_magnitude: grad.length(),
        tau: 1e-6,
    };
    let mut scene = Scene::new(Classification::with_windows([
        window(0.1, 0.95, 0.05),
        None,
        None,
        None,
    ]));
    scene.background = [0.1, 0.2, 0.3];
    (g, norm, stats, scene)
}

#[test]
fn camera_inside_the_volume_gives_finite_non_background_pixels() {
    let (g, norm, stats, mut scene) = ramp_setup([24, 24, 24]);
    let volume = ReferenceVolume::new(g.dims, &norm).unwrap();
    scene.effects = Effects {
        mode: RenderMode::Dvr,
        curvature: true,
        shading: true,
        gradient_source: GradientSource::OnTheFly,
        quality: Default::default(),
        vessels: false,
        brain: morphray::passes::brain::BrainSwitch::Off,
        lighting: Default::default(),
    };
    // Zoom 8 puts the eye at 3.86 / 8 = 0.48 bounding radii from the centre, inside the cube
    // (half side = 0.577 radii). Check that, then that every ray starts at t = 0.
    scene.camera.zoom = 8.0;
    for (az, el) in [(0.0, 0.0), (47.0, 12.0), (200.0, -70.0)] {
        scene.camera.azimuth_deg = az;
        scene.camera.elevation_deg = el;
        let r =
            ReferenceRaymarch::new(&scene, &g, &stats, &volume, &ReferenceDerived::NONE, 24, 24)
                .unwrap();
        let eye = r.camera_rays().origin;
        assert!(eye.cmpgt(DVec3::splat(-0.5)).all() && eye.cmplt(DVec3::splat(23.5)).all());
        for y in 0..24 {
            for x in 0..24 {
                let plan = r.ray(x, y);
                assert_eq!(plan.hit.map(|h| h.0), Some(0.0), "starts inside");
                assert!(plan.count > 0);
                let p = r.pixel(x, y);
                assert!(p.iter().all(|c| c.is_finite()));
                assert_eq!(p[3], 1.0);
                assert!(
                    max_abs_diff(&p, &background_of(&scene)) > 1e-3,
                    "{x} {y}: {p:?}"
                );
            }
        }
    }
}

#[test]
fn rays_exactly_on_faces_and_edges_are_finite_and_see_the_border_voxels() {
    // Identity affine, 16^3: the box is [-0.5, 15.5]^3 mm, centre 7.5. The anterior
    // orthographic view is exactly axis-aligned (forward -y, right -x, up +z, computed from
    // sin 0 / cos 0), and with an odd image the centre pixel's ray passes through the look-at
    // point, which pan moves to (7.5 - pan_x, ., 7.5 + pan_y). pan_x = 8 puts the ray on the
    // face x = -0.5 exactly (all values here are exact in f64).
    let (g, norm, stats, mut scene) = ramp_setup([16, 16, 16]);
    let volume = ReferenceVolume::new(g.dims, &norm).unwrap();
    let magnitude = vec![stats.max_magnitude; norm.len()];
    let derived = ReferenceDerived {
        gradient_magnitude: Some(&magnitude),
        ..ReferenceDerived::NONE
    };
    scene.camera = orthographic_anterior();
    let bg = background_of(&scene);
    let centre_pixel = |scene: &Scene| {
        let r = ReferenceRaymarch::new(scene, &g, &stats, &volume, &derived, 17, 17).unwrap();
        (r.ray(8, 8), r.pixel(8, 8))
    };
    let mut on_face_hits = 0;
    for (pan, face) in [
        ([8.0, 0.0], [Some(-0.5), None]),
        ([-8.0, 0.0], [Some(15.5), None]),
        ([0.0, -8.0], [None, Some(-0.5)]),
        ([0.0, 8.0], [None, Some(15.5)]),
        ([8.0, 8.0], [Some(-0.5), Some(15.5)]), // edges
        ([-8.0, -8.0], [Some(15.5), Some(-0.5)]),
        ([8.0, -8.0], [Some(-0.5), Some(-0.5)]),
    ] {
        scene.camera.pan_mm = pan;
        let (plan, on_face) = centre_pixel(&scene);
        assert!(
            on_face.iter().all(|c| c.is_finite()) && on_face[3] == 1.0,
            "{pan:?}"
        );
        // The ray lies in the face plane(s): exact positions, zero direction components.
        let mut expect_hit = true;
        for (axis, plane) in [(0, face[0]), (2, face[1])] {
            if let Some(plane) = plane {
                assert_eq!(plan.origin[axis], plane, "{pan:?}");
                assert_eq!(plan.direction[axis], 0.0, "{pan:?}");
                // intersect_box treats a zero direction component as a containment test on the
                // closed slab, so a ray in either face plane is inside, whatever the zero's sign.
                let _ = plane;
                expect_hit &= true;
            }
        }
        // 1e-6 mm inside, the ray always hits. Clamp-to-edge: on the face the texel
        // coordinate is -0.5 (or dim - 0.5), whose two taps both clamp to the border voxel, and
        // 1e-6 mm inside the taps are the border voxel twice again: same positions along the
        // ray, same values, identical pixels (tolerance 0) when the face ray counts as a hit.
        scene.camera.pan_mm = pan.map(|p| p - 1e-6 * p.signum());
        let (inner_plan, inward) = centre_pixel(&scene);
        assert!(inward != bg, "{pan:?}");
        if expect_hit {
            assert_eq!(plan.hit.map(|(t0, t1)| t1 - t0), Some(16.0), "{pan:?}");
            assert_eq!(plan.count, inner_plan.count);
            assert_eq!(inward, on_face, "{pan:?}");
            on_face_hits += 1;
        } else {
            assert_eq!((plan.hit, on_face), (None, bg), "{pan:?}");
        }
        // 1e-5 mm outside is within the face tolerance (about 2e-4 voxel here: what f32 rounding
        // and fused multiply-adds can move an origin on the face): still the face ray's pixel.
        scene.camera.pan_mm = pan.map(|p| p + 1e-5 * p.signum());
        let (_, within) = centre_pixel(&scene);
        assert_eq!(within, on_face, "{pan:?}");
        // 1e-3 mm outside, the ray misses: exactly the background.
        scene.camera.pan_mm = pan.map(|p| p + 1e-3 * p.signum());
        let (miss, outside) = centre_pixel(&scene);
        assert_eq!((miss.hit, outside), (None, bg), "{pan:?}");
    }
    assert!(on_face_hits >= 2, "{on_face_hits}");
}

#[test]
fn grazing_rays_are_finite() {
    // Views that are axis-aligned only up to sin/cos rounding (azimuth 90, elevation 90: a
    // direction component of ~6e-17), and the body diagonal, with the centre ray panned onto
    // faces, edges and the corner, and 1e-12 .. 1e-3 mm off them. All effects on, both
    // gradient sources. Only finiteness (and alpha 1) is claimed: which side of the face a
    // 1e-17-oblique ray lands on is rounding.
    let (g, norm, stats, mut scene) = ramp_setup([12, 12, 12]);
    let volume = ReferenceVolume::new(g.dims, &norm).unwrap();
    let n = norm.len();
    let magnitude = vec![stats.max_magnitude; n];
    let curvature = vec![0.0; n];
    let normals = vec![[0.0, 0.6, 0.8]; n];
    let derived = ReferenceDerived {
        gradient_magnitude: Some(&magnitude),
        curvature: Some(&curvature),
        normals: Some(&normals),
    };
    let diagonal_el = (1.0 / 2f64.sqrt()).atan().to_degrees();
    let corner = DVec3::splat(-0.5);
    let mut hits = 0;
    for source in [GradientSource::Precomputed, GradientSource::OnTheFly] {
        scene.effects = Effects {
            mode: RenderMode::Dvr,
            curvature: true,
            shading: true,
            gradient_source: source,
            quality: Default::default(),
            vessels: false,
            brain: morphray::passes::brain::BrainSwitch::Off,
            lighting: Default::default(),
        };
        for (az, el) in [
            (90.0, 0.0),
            (0.0, 90.0),
            (180.0, -90.0),
            (225.0, -diagonal_el),
        ] {
            let camera = Camera {
                azimuth_deg: az,
                elevation_deg: el,
                projection: Projection::Orthographic,
                ..Camera::default()
            };
            let rays = camera.rays(g.world_bounds(), 9, 9);
            let centre = (g.world_bounds().0 + g.world_bounds().1) * 0.5;
            // Pan that puts the centre ray through the corner, and through the middle of two
            // edges / faces that meet there.
            let to_corner = corner - centre;
            let targets = [
                to_corner,
                DVec3::new(to_corner.x, to_corner.y, 0.0),
                DVec3::new(to_corner.x, 0.0, 0.0),
                DVec3::new(0.0, to_corner.y, 0.0),
                DVec3::new(0.0, 0.0, to_corner.z),
            ];
            for target in targets {
                let base = [target.dot(rays.right), target.dot(rays.up)];
                for delta in [0.0, 1e-12, -1e-12, 1e-9, -1e-9, 1e-3, -1e-3] {
                    for step in [0.125, 1.0, 4.0] {
                        scene.camera = Camera {
                            pan_mm: [base[0] + delta, base[1] - delta],
                            ..camera
                        };
                        scene.step_voxels = step;
                        let r = ReferenceRaymarch::new(&scene, &g, &stats, &volume, &derived, 9, 9)
                            .unwrap();
                        for (x, y) in [(4, 4), (3, 4), (4, 5), (0, 0)] {
                            let plan = r.ray(x, y);
                            hits += usize::from(plan.count > 0);
                            let p = r.pixel(x, y);
                            assert!(
                                p.iter().all(|c| c.is_finite()) && p[3] == 1.0,
                                "{az} {el} {target} {delta} {step}: {p:?}"
                            );
                        }
                    }
                }
            }
        }
    }
    assert!(hits > 100, "the sweep must actually touch the box: {hits}");
}

// ---------------------------------------------------------------------------------------------
// Anisotropic and flipped grids of one world-space object

/// Renders `f` (world space, mm) sampled on `g`; gradients on the fly.
fn render_world_object(
    g: &VolumeGeometry,
    f: &dyn Fn(DVec3) -> f64,
    scene: &Scene,
    stats: &GradientStats,
    size: u32,
) -> Vec<[f64; 4]> {
    let norm = sample_world(g, f);
    let volume = ReferenceVolume::new(g.dims, &norm).unwrap();
    render(
        scene,
        g,
        stats,
        &volume,
        &ReferenceDerived::NONE,
        size,
        size,
    )
    .unwrap()
}

fn object_scene() -> Scene {
    let mut scene = Scene::new(Classification::with_windows([
        window(0.3, 0.45, 0.03),
        window(0.45, 0.6, 0.03),
        window(0.6, 0.75, 0.03),
        None,
    ]));
    scene.classification.show_only(&TissueClass::ALL);
    scene.effects = Effects {
        mode: RenderMode::Dvr,
        curvature: true,
        shading: true,
        gradient_source: GradientSource::OnTheFly,
        quality: Default::default(),
        vessels: false,
        brain: morphray::passes::brain::BrainSwitch::Off,
        lighting: Default::default(),
    };
    scene.camera = Camera {
        azimuth_deg: 30.0,
        elevation_deg: 20.0,
        zoom: 1.3,
        ..Camera::default()
    };
    scene.background = [0.05, 0.05, 0.1];
    scene
}

#[test]
fn flipped_grid_renders_the_same_image_as_the_isotropic_one() {
    // A smooth blob in world space on the 1 mm grid of [0, 24]^3 and on the same grid with x
    // flipped (spacing -1, voxel 0 at x = 23.5). Both grids have their voxel centres at the
    // same world points, so the data are the same numbers, reindexed; trilinear reconstruction,
    // the on-the-fly stencils (taps at +-1 voxel = +-1 mm either way, the x difference changing
    // sign and M = A^-T changing it back) and the clamp bands coincide. The images may differ
    // only by f64 rounding of the transforms: 1e-9 (observed ~1e-15; a real mirror bug moves
    // the off-centre blob by several pixels, an O(1) difference).
    let iso = box_geometry([1.0, 1.0, 1.0], 24.0);
    let flipped = box_geometry([-1.0, 1.0, 1.0], 24.0);
    assert_eq!(voxel_world(&flipped, 0, 0, 0), DVec3::new(23.5, 0.5, 0.5));
    let centre = DVec3::new(9.0, 13.0, 11.0);
    let blob = |x: DVec3| {
        let d = x - centre;
        0.15 + 0.7 * (-(d.x * d.x / 30.0 + d.y * d.y / 20.0 + d.z * d.z / 40.0)).exp()
    };
    let stats = GradientStats {
        max_magnitude: 0.12,
        tau: 1e-5,
    };
    let mut scene = object_scene();
    for jitter_on in [false, true] {
        scene.jitter = jitter_on;
        let a = render_world_object(&iso, &blob, &scene, &stats, 28);
        let b = render_world_object(&flipped, &blob, &scene, &stats, 28);
        let visible = a.iter().filter(|p| **p != background_of(&scene)).count();
        assert!(visible > 100, "{visible}");
        let worst = a
            .iter()
            .zip(&b)
            .map(|(p, q)| max_abs_diff(p, q))
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{worst:e}");
    }
}

#[test]
fn anisotropic_grids_render_a_multilinear_object_like_an_isotropic_grid_of_the_same_voxel_length() {
    // Object: v(u) = 0.5 + b . u + e1 u_x u_y + e2 u_y u_z + e3 u_x u_z (u = x - c, world mm) on
    // [0, 24]^3: curved (hyperbolic) isosurfaces with non-zero curvature, sampled on an
    // isotropic 0.5 mm grid, on 0.5 x 1 x 3 mm, and on -0.5 x 1 x 3 mm (flipped too).
    //
    // Why these three: a "voxel" of step and of opacity is the finest axis (voxel_mm), so a
    // scene means the same sample spacing and the same absorption per mm only on grids with the
    // same voxel_mm. An isotropic 1 mm grid (voxel_mm = 1) absorbs half as much per mm as
    // these and cannot give the same image without changing the scene; compensating the
    // opacity is exact only where the window weight is 0 or 1, since 1 - (1 - w o)^r is not
    // linear in w. The flipped 1 mm test above is the 1 mm comparison.
    //
    // Why the images agree: the grids are axis-aligned in world space, so v is multilinear in
    // index coordinates on each of them, and trilinear interpolation reproduces multilinear
    // functions exactly, as do the central-difference stencils (first, second and mixed) of
    // the on-the-fly gradient and curvature; with world gradient = A^-T g_idx and
    // H_world = A^-T H_idx A^-1, v, |g|, the normal and k are the same at the same world point
    // on every grid, and the sample points coincide (same dt in mm, same jitter). Exact, that
    // is, wherever no tap clamps: taps clamp within 1.5 voxels of a face (on-the-fly taps at
    // +-1 voxel, each trilinear within half a voxel), 4.5 mm on the 3 mm axis. Pixels are
    // compared where every point of the ray that the window can classify lies at least 5 mm
    // inside the box; there the images agree to rounding: 1e-9. (A wrong scale or flip moves
    // v by O(0.01) along the ray, shifting the visible shell by millimetres: an O(0.1) change.)
    let c = DVec3::splat(12.0);
    let b = DVec3::new(0.0094, 0.0163, 0.0068); // ~0.02 along the view direction
    let object = move |x: DVec3| {
        let u = x - c;
        0.5 + b.dot(u) + 0.0008 * u.x * u.y - 0.0006 * u.y * u.z + 0.0005 * u.x * u.z
    };
    let stats = GradientStats {
        max_magnitude: 0.03,
        tau: 1e-6,
    };
    let mut scene = object_scene();
    scene.classification =
        Classification::with_windows([window(0.46, 0.54, 0.02), None, None, None]);
    scene.classification.tissues[0].opacity = 0.3;
    scene.camera.projection = Projection::Orthographic;
    scene.camera.zoom = 1.8;
    scene.step_voxels = 1.0;
    let size = 32;
    let iso = box_geometry([0.5, 0.5, 0.5], 24.0);
    let rays = scene.camera.rays(iso.world_bounds(), size, size);
    let (lo, hi) = iso.world_bounds();
    // Samples are classified where |v - 0.5| < 0.04 + 0.02. Scan each ray every 0.05 mm; v
    // changes by < 0.003 between scan points (|grad v| < 0.05 / mm in the box), so a margin of
    // 0.005 catches every classifiable sample position.
    let comparable: Vec<bool> = (0..size * size)
        .map(|i| {
            let (o, d) = rays.ray(f64::from(i % size), f64::from(i / size), size, size);
            let Some(length) = world_chord(o, d, lo, hi) else {
                return true; // a miss is the background on every grid
            };
            let t_near = (0..3)
                .map(|a| ((lo[a] - o[a]) / d[a]).min((hi[a] - o[a]) / d[a]))
                .fold(f64::NEG_INFINITY, f64::max)
                .max(0.0);
            (0..=(length / 0.05) as usize).all(|s| {
                let p = o + d * (t_near + s as f64 * 0.05);
                (object(p) - 0.5).abs() > 0.065
                    || (p.cmpge(DVec3::splat(5.0)).all() && p.cmple(DVec3::splat(19.0)).all())
            })
        })
        .collect();
    for jitter_on in [false, true] {
        scene.jitter = jitter_on;
        let reference = render_world_object(&iso, &object, &scene, &stats, size);
        let shown = reference
            .iter()
            .zip(&comparable)
            .filter(|(p, c)| **c && max_abs_diff(p, &background_of(&scene)) > 0.05)
            .count();
        assert!(
            shown > 60,
            "the comparable pixels must show the object: {shown}"
        );
        for spacing in [[0.5, 1.0, 3.0], [-0.5, 1.0, 3.0]] {
            let g = box_geometry(spacing, 24.0);
            assert_eq!(g.voxel_mm, iso.voxel_mm);
            let image = render_world_object(&g, &object, &scene, &stats, size);
            let mut worst: f64 = 0.0;
            for ((p, q), &c) in image.iter().zip(&reference).zip(&comparable) {
                if c {
                    worst = worst.max(max_abs_diff(p, q));
                }
            }
            assert!(worst < 1e-9, "{spacing:?} jitter {jitter_on}: {worst:e}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Tissue toggles

#[test]
fn hiding_a_tissue_removes_exactly_its_contribution() {
    // Volume at 0.5 (unclassified) with a bright blob A (peak 0.8, WM window [0.7, 0.9]) and a
    // dark blob B (trough 0.2, CSF window [0.1, 0.3]), 20 mm apart along x. A's values stay in
    // [0.5, 0.8] and B's in [0.2, 0.5], so no sample near one blob ever falls in the other's
    // window (the windows end at 0.32 and start at 0.68 with their edges).
    let g = identity_geometry([40, 20, 24]);
    let (ca, cb) = (DVec3::new(10.0, 9.5, 11.5), DVec3::new(30.0, 9.5, 11.5));
    let sigma2 = 9.0;
    let bump = |x: DVec3, c: DVec3| (-(x - c).length_squared() / (2.0 * sigma2)).exp();
    let norm = sample_world(&g, |x| 0.5 + 0.3 * bump(x, ca) - 0.3 * bump(x, cb));
    let volume = ReferenceVolume::new(g.dims, &norm).unwrap();
    let stats = GradientStats {
        max_magnitude: 0.3 / 3.0 * (-0.5f64).exp(), // max of the Gaussian's slope
        tau: 1e-6,
    };
    let mut classification =
        Classification::with_windows([window(0.1, 0.3, 0.02), None, window(0.7, 0.9, 0.02), None]);
    classification.show_only(&[TissueClass::Csf, TissueClass::Wm]);
    let mut scene = Scene::new(classification);
    scene.camera = orthographic_anterior();
    scene.background = [0.2, 0.1, 0.0];
    scene.effects = Effects {
        mode: RenderMode::Dvr,
        curvature: true,
        shading: true,
        gradient_source: GradientSource::OnTheFly,
        quality: Default::default(),
        vessels: false,
        brain: morphray::passes::brain::BrainSwitch::Off,
        lighting: Default::default(),
    };
    let size = 48;
    let draw = |scene: &Scene| {
        render(
            scene,
            &g,
            &stats,
            &volume,
            &ReferenceDerived::NONE,
            size,
            size,
        )
        .unwrap()
    };
    let both = draw(&scene);
    let bg = background_of(&scene);
    // Which pixels see which blob, from geometry alone: the rays run along y, so a ray at
    // lateral distance d from a blob centre meets at most 0.5 + 0.3 exp(-d^2 / 18). d <= 2.5
    // reaches 0.712, well inside the window edge (0.68; trilinear error of this Gaussian on a
    // 1 mm grid is < 0.3 / 9 / 8 < 0.005); d >= 3.5 stays below 0.653 < 0.68 - 0.005. Pixels in
    // between are left out.
    let rays = scene.camera.rays(g.world_bounds(), size, size);
    let lateral = |i: u32, c: DVec3| {
        let (o, _) = rays.ray(f64::from(i % size), f64::from(i / size), size, size);
        ((o.x - c.x).powi(2) + (o.z - c.z).powi(2)).sqrt()
    };
    for (hidden, centre, other) in [(TissueClass::Wm, ca, cb), (TissueClass::Csf, cb, ca)] {
        let mut toggled = scene;
        toggled.classification.style_mut(hidden).visible = false;
        let without = draw(&toggled);
        let (mut only_hidden, mut unchanged) = (0, 0);
        for i in 0..size * size {
            let (d_hidden, d_other) = (lateral(i, centre), lateral(i, other));
            let (before, after) = (both[i as usize], without[i as usize]);
            if d_hidden <= 2.5 {
                assert!(d_other > 3.5);
                // Sees only the hidden blob: it was drawn, and now it is exactly the
                // background (every remaining sample has f = 0; tolerance 0).
                assert!(
                    max_abs_diff(&before, &bg) > 1e-3,
                    "pixel {i} did not show the blob"
                );
                assert_eq!(after, bg, "pixel {i}");
                only_hidden += 1;
            } else if d_hidden >= 3.5 {
                // Never meets the hidden tissue: the same samples composite the same values
                // in the same order, so the pixel is bit for bit unchanged (tolerance 0).
                assert_eq!(after, before, "pixel {i}");
                unchanged += usize::from(d_other <= 2.5);
            }
        }
        assert!(
            only_hidden >= 12 && unchanged >= 12,
            "{only_hidden} {unchanged}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// MIP and MinIP

#[test]
fn mip_shows_the_bright_region() {
    // Noise in [0, 0.2] with a bright block of 0.9 at voxels x, z in 10..=13, y in 8..=15. Inside
    // [10, 13] x [8, 15] x [10, 13] (index = world mm here) all 8 trilinear taps are 0.9, so the
    // sample is exactly 0.9 (the reference's lerp is exact on equal values). A ray along y at
    // x, z in that square crosses 7 mm of it, so with any step <= 1 voxel a sample lands there:
    // the pixel is exactly 0.9 (window [0, 1]; tolerance 0). Rays more than 1 mm outside the
    // block in x or z only blend noise: <= 0.2.
    let g = identity_geometry([24, 24, 24]);
    let mut noise = Noise(11);
    let mut norm = Vec::new();
    for k in 0..24 {
        for j in 0..24 {
            for i in 0..24 {
                let bright =
                    (10..=13).contains(&i) && (8..=15).contains(&j) && (10..=13).contains(&k);
                norm.push(if bright { 0.9 } else { 0.2 * noise.next() });
            }
        }
    }
    let volume = ReferenceVolume::new(g.dims, &norm).unwrap();
    let mut scene = Scene::new(Classification::with_windows([None; 4]));
    scene.effects.mode = RenderMode::Mip;
    scene.camera = Camera {
        zoom: 1.5,
        ..orthographic_anterior()
    };
    scene.background = [0.3, 0.0, 0.0];
    let size = 40;
    let stats = GradientStats {
        max_magnitude: 0.0,
        tau: 0.0,
    };
    for step in [0.25, 0.5, 1.0] {
        scene.step_voxels = step;
        let r = ReferenceRaymarch::new(
            &scene,
            &g,
            &stats,
            &volume,
            &ReferenceDerived::NONE,
            size,
            size,
        )
        .unwrap();
        let rays = *r.camera_rays();
        let (mut bright, mut dark) = (0, 0);
        for y in 0..size {
            for x in 0..size {
                let (o, _) = rays.ray(f64::from(x), f64::from(y), size, size);
                let p = r.pixel(x, y);
                if r.ray(x, y).count == 0 {
                    assert_eq!(p, background_of(&scene));
                    continue;
                }
                assert!(p[0] == p[1] && p[1] == p[2] && p[3] == 1.0);
                assert!(p[0] <= 0.9);
                let inside = |v: f64| (10.0..=13.0).contains(&v);
                let far = |v: f64| !(9.0..=14.0).contains(&v);
                if inside(o.x) && inside(o.z) {
                    assert_eq!(p[0], 0.9, "{x} {y}");
                    bright += 1;
                } else if far(o.x) || far(o.z) {
                    assert!(p[0] <= 0.2, "{x} {y}: {}", p[0]);
                    dark += 1;
                }
            }
        }
        assert!(bright >= 9 && dark > 500, "{bright} {dark}");
    }
    // The display window clamps: with [0.25, 0.5] the bright block is white (1, not 2.6) and
    // the noise (<= 0.2) black (0, not negative); rays through the trilinear blend zone at the
    // block's edge may land in between, but never outside [0, 1].
    scene.intensity_window = [0.25, 0.5];
    scene.step_voxels = 0.5;
    let r = ReferenceRaymarch::new(
        &scene,
        &g,
        &stats,
        &volume,
        &ReferenceDerived::NONE,
        size,
        size,
    )
    .unwrap();
    let rays = *r.camera_rays();
    let bg = background_of(&scene);
    let (mut white, mut black) = (0, 0);
    for y in 0..size {
        for x in 0..size {
            let p = r.pixel(x, y);
            if p == bg {
                continue;
            }
            assert!((0.0..=1.0).contains(&p[0]), "{x} {y}: {}", p[0]);
            let (o, _) = rays.ray(f64::from(x), f64::from(y), size, size);
            let inside = |v: f64| (10.0..=13.0).contains(&v);
            let far = |v: f64| !(9.0..=14.0).contains(&v);
            if inside(o.x) && inside(o.z) {
                assert_eq!(p[0], 1.0, "{x} {y}");
                white += 1;
            } else if far(o.x) || far(o.z) {
                assert_eq!(p[0], 0.0, "{x} {y}");
                black += 1;
            }
        }
    }
    assert!(white >= 9 && black > 500, "{white} {black}");
}

#[test]
fn minip_above_the_floor_shows_the_darkest_tissue_value() {
    // Air (0) in the voxel columns x <= 5, tissue noise in [0.5, 0.9] elsewhere, and a dark
    // block of 0.3 at x in 12..=15, y in 8..=15, z in 10..=13. Floor 0.1: air never counts.
    // - Rays at x <= 5 only meet air (at x = 5 the tap weights put 0 on x = 6): no sample
    //   reaches the floor, the pixel is the background (tolerance 0).
    // - Rays with x, z inside the dark block's exact region [12, 15] x [10, 13] sample 0.3
    //   exactly, and nothing darker that passes the floor: the pixel is 0.3 (tolerance 0).
    // - Rays at x >= 7 more than 1 mm away from the block sample tissue blends only: >= 0.5.
    // - Without the floor (0), the air columns show black instead: the floor's purpose.
    let g = identity_geometry([24, 24, 24]);
    let mut noise = Noise(5);
    let mut norm = Vec::new();
    for k in 0..24 {
        for j in 0..24 {
            for i in 0..24 {
                let dark =
                    (12..=15).contains(&i) && (8..=15).contains(&j) && (10..=13).contains(&k);
                norm.push(if i <= 5 {
                    0.0
                } else if dark {
                    0.3
                } else {
                    0.5 + 0.4 * noise.next()
                });
            }
        }
    }
    let volume = ReferenceVolume::new(g.dims, &norm).unwrap();
    let mut scene = Scene::new(Classification::with_windows([None; 4]));
    scene.effects.mode = RenderMode::MinIp;
    scene.minip_floor = 0.1;
    scene.camera = Camera {
        zoom: 1.5,
        ..orthographic_anterior()
    };
    scene.background = [0.0, 0.4, 0.0];
    let bg = background_of(&scene);
    let stats = GradientStats {
        max_magnitude: 0.0,
        tau: 0.0,
    };
    let size = 40;
    let r = ReferenceRaymarch::new(
        &scene,
        &g,
        &stats,
        &volume,
        &ReferenceDerived::NONE,
        size,
        size,
    )
    .unwrap();
    let mut no_floor = scene;
    no_floor.minip_floor = 0.0;
    let r0 = ReferenceRaymarch::new(
        &no_floor,
        &g,
        &stats,
        &volume,
        &ReferenceDerived::NONE,
        size,
        size,
    )
    .unwrap();
    let rays = *r.camera_rays();
    let (mut air, mut darkest, mut tissue) = (0, 0, 0);
    let mut darkest_seen = f64::INFINITY;
    for y in 0..size {
        for x in 0..size {
            if r.ray(x, y).count == 0 {
                continue;
            }
            let (o, _) = rays.ray(f64::from(x), f64::from(y), size, size);
            let p = r.pixel(x, y);
            if o.x <= 5.0 {
                assert_eq!(p, bg, "{x} {y}");
                assert_eq!(r0.pixel(x, y), [0.0, 0.0, 0.0, 1.0]);
                air += 1;
                continue;
            }
            if o.x >= 7.0 {
                darkest_seen = darkest_seen.min(p[0]);
            }
            let inside_x = (12.0..=15.0).contains(&o.x);
            let inside_z = (10.0..=13.0).contains(&o.z);
            if inside_x && inside_z {
                assert_eq!(p, [0.3, 0.3, 0.3, 1.0], "{x} {y}");
                darkest += 1;
            } else if o.x >= 7.0 && (!(11.0..=16.0).contains(&o.x) || !(9.0..=14.0).contains(&o.z))
            {
                assert!(p[0] >= 0.5, "{x} {y}: {}", p[0]);
                tissue += 1;
            }
        }
    }
    // Away from the air boundary, the image's darkest value is the dark block's.
    assert_eq!(darkest_seen, 0.3);
    assert!(
        air > 50 && darkest >= 9 && tissue > 300,
        "{air} {darkest} {tissue}"
    );
}

// ---------------------------------------------------------------------------------------------
// Robustness

fn random_geometry(noise: &mut Noise, dims: [u32; 3]) -> VolumeGeometry {
    let mut spacing = [0.0; 3];
    for s in &mut spacing {
        let magnitude = 0.3 * 10f64.powf(noise.next()); // 0.3 .. 3 mm
        *s = if noise.next() < 0.3 {
            -magnitude
        } else {
            magnitude
        };
    }
    // A rotation about z (oblique acquisitions) half of the time.
    let angle = if noise.next() < 0.5 {
        noise.next() * std::f64::consts::TAU
    } else {
        0.0
    };
    let (c, s) = (angle.cos(), angle.sin());
    let affine = [
        [
            c * spacing[0],
            -s * spacing[1],
            0.0,
            100.0 * noise.next() - 50.0,
        ],
        [
            s * spacing[0],
            c * spacing[1],
            0.0,
            100.0 * noise.next() - 50.0,
        ],
        [0.0, 0.0, spacing[2], 100.0 * noise.next() - 50.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    VolumeGeometry::new(dims, affine).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    /// No NaN or infinity in any output, for random volumes, affines, cameras (including zoom
    /// from 1e-6 to 1e6, inside and far outside the volume), steps 0.125 .. 4 voxels, every
    /// mode and effect, jitter, and tiny images.
    #[test]
    fn random_scenes_render_finite_pixels(
        seed in any::<u64>(),
        dims in prop::array::uniform3(2u32..14),
        azimuth in -360.0f64..360.0,
        elevation in -100.0f64..100.0,
        log_zoom in -6.0f64..6.0,
        pan in prop::array::uniform2(-40.0f64..40.0),
        fov in prop::option::of(0.5f64..179.0),
        step in 0.125f64..4.0,
        mode in prop::sample::select(vec![RenderMode::Dvr, RenderMode::Mip, RenderMode::MinIp]),
        flags in prop::array::uniform4(any::<bool>()),
        strength in -2.0f64..4.0,
        early_termination in 0.3f64..1.2,
        size in (1u32..10, 1u32..10),
    ) {
        let mut noise = Noise(seed);
        let g = random_geometry(&mut noise, dims);
        let n = (dims[0] * dims[1] * dims[2]) as usize;
        let norm: Vec<f64> = (0..n).map(|_| noise.next()).collect();
        let magnitude: Vec<f64> = (0..n).map(|_| 0.2 * noise.next()).collect();
        let curvature: Vec<f64> = (0..n).map(|_| noise.next() - 0.5).collect();
        let normals: Vec<[f64; 3]> = (0..n)
            .map(|_| if noise.next() < 0.2 { [0.0; 3] } else { [noise.next(), -noise.next(), 0.3] })
            .collect();
        let derived = ReferenceDerived {
            gradient_magnitude: Some(&magnitude),
            curvature: Some(&curvature),
            normals: Some(&normals),
        };
        let volume = ReferenceVolume::new(dims, &norm).unwrap();
        let mut scene = Scene::new(Classification::with_windows([
            window(0.0, 0.3, 0.05),
            window(0.3, 0.6, 0.05),
            window(0.6, 0.9, 0.05),
            window(0.9, 1.0, 0.05),
        ]));
        scene.classification.show_only(&TissueClass::ALL);
        scene.camera = Camera {
            azimuth_deg: azimuth,
            elevation_deg: elevation,
            zoom: 10f64.powf(log_zoom),
            pan_mm: pan,
            projection: fov.map_or(Projection::Orthographic, |f| Projection::Perspective { fov_y_deg: f }),
        };
        scene.step_voxels = step;
        scene.effects = Effects {
            mode,
            curvature: flags[0],
            shading: flags[1],
            gradient_source: if flags[2] { GradientSource::OnTheFly } else { GradientSource::Precomputed },
            quality: Default::default(),
            vessels: false,
            brain: morphray::passes::brain::BrainSwitch::Off,
            lighting: Default::default(),
        };
        scene.jitter = flags[3];
        scene.frame = seed as u32;
        scene.curvature_strength = strength as f32;
        scene.early_termination = early_termination as f32;
        scene.background = [0.1, 0.2, 0.3];
        scene.minip_floor = 0.2;
        let stats = GradientStats { max_magnitude: 0.15, tau: 1e-3 };
        let image = render(&scene, &g, &stats, &volume, &derived, size.0, size.1).unwrap();
        prop_assert_eq!(image.len(), (size.0 * size.1) as usize);
        for p in &image {
            prop_assert!(p.iter().all(|c| c.is_finite()), "{:?}", p);
            prop_assert_eq!(p[3], 1.0);
        }
    }
}
