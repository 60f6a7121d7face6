//! Eigenvalues of symmetric 3x3 matrices (NUMERICS.md row "eigenvalues of a symmetric 3x3"):
//! the f64 twin (`reference::eigen`) against prescribed spectra, and the shader routine
//! (`shaders/include/eigen3.glsl`, through the probe `shaders/probes/eigen_probe.comp`) against
//! the twin on the hard cases, with the naive closed form on the same device failing the bound.

mod common;

use common::volumes::Rng;
use morphray::passes::eigen_probe::EigenProbe;
use morphray::reference::Sym3;
use morphray::reference::eigen::sym3_eigenvalues;

/// GPU (f32) vs f64 bound, relative to the matrix's largest |eigenvalue|, with an absolute floor
/// for subnormals (Vulkan may flush them). Jacobi in f32 is backward stable: a few eps (6e-8).
/// Measured on lavapipe: see `gpu_eigenvalues_are_within_the_bound_where_the_naive_form_fails`'s
/// printed worst case (ACCURACY.md).
const GPU_REL_BOUND: f64 = 1e-6;
const GPU_ABS_FLOOR: f64 = 1e-37;

/// A rotation from a random unit quaternion.
fn rotation(rng: &mut Rng) -> [[f64; 3]; 3] {
    let mut q = [0.0; 4];
    for v in &mut q {
        *v = rng.range(-1.0, 1.0);
    }
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-9);
    let [w, x, y, z] = q.map(|v| v / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Q diag(l) Q^T.
fn with_spectrum(l: [f64; 3], q: &[[f64; 3]; 3]) -> Sym3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| q[i][k] * l[k] * q[j][k]).sum();
        }
    }
    Sym3::from_matrix(&m)
}

/// The hard spectra of NUMERICS.md (ascending).
fn hard_spectra() -> Vec<(&'static str, [f64; 3])> {
    let mut out = vec![
        ("distinct", [1.0, 2.0, 3.0]),
        ("triple", [2.0, 2.0, 2.0]),
        ("pair", [1.0, 1.0, 2.0]),
        ("negative pair", [-3.0, -3.0, 0.5]),
        ("nearly repeated 1e-3", [1.0, 1.001, 2.0]),
        ("nearly repeated 1e-5", [-1.0, -1.0 + 1e-5, 3.0]),
        ("nearly triple", [1.0, 1.0 + 1e-6, 1.0 + 2e-6]),
        ("rank 1", [0.0, 0.0, 1.0]),
        ("rank 2", [-2.0, 0.0, 1.0]),
        ("wide", [-1e-3, 1.0, 1e3]),
        ("zero", [0.0, 0.0, 0.0]),
    ];
    let base = out.clone();
    for (scale, label) in [
        (1e30, "x 1e30"),
        (1e-30, "x 1e-30"),
        (1e36, "x 1e36"),
        (1e-36, "x 1e-36"),
    ] {
        for (name, l) in &base {
            let leaked: &'static str = Box::leak(format!("{name} {label}").into_boxed_str());
            out.push((leaked, l.map(|v| v * scale)));
        }
    }
    out
}

fn max_abs(l: &[f64; 3]) -> f64 {
    l.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

#[test]
fn twin_recovers_prescribed_spectra_on_the_hard_cases() {
    let mut rng = Rng(15);
    for (name, l) in hard_spectra() {
        for extra in [1e-300, 1.0, 1e300] {
            let l = l.map(|v| v * extra);
            for _ in 0..20 {
                let a = with_spectrum(l, &rotation(&mut rng));
                let got = sym3_eigenvalues(&a);
                let tol = 1e-13 * max_abs(&l) + 1e-320;
                for k in 0..3 {
                    assert!(
                        (got[k] - l[k]).abs() <= tol,
                        "{name} x {extra:e}: {got:?} vs {l:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn twin_gives_zeros_for_non_finite_entries() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for slot in 0..6 {
            let mut e = [1.0, 2.0, 3.0, 0.5, 0.25, 0.125];
            e[slot] = bad;
            let a = Sym3 {
                xx: e[0],
                yy: e[1],
                zz: e[2],
                xy: e[3],
                xz: e[4],
                yz: e[5],
            };
            assert_eq!(sym3_eigenvalues(&a), [0.0; 3]);
        }
    }
}

fn entries(a: &Sym3) -> [f32; 6] {
    [a.xx, a.yy, a.zz, a.xy, a.xz, a.yz].map(|v| v as f32)
}

fn from_f32(e: &[f32; 6]) -> Sym3 {
    Sym3 {
        xx: e[0] as f64,
        yy: e[1] as f64,
        zz: e[2] as f64,
        xy: e[3] as f64,
        xz: e[4] as f64,
        yz: e[5] as f64,
    }
}

/// Worst error of `got` against the twin on the same f32 entries, relative to |A|'s largest
/// eigenvalue (+ the floor): the error over the bound, and the case.
fn excess(got: [f32; 3], exact: [f64; 3]) -> f64 {
    let scale = GPU_REL_BOUND * max_abs(&exact) + GPU_ABS_FLOOR;
    (0..3)
        .map(|k| {
            let e = (got[k] as f64 - exact[k]).abs();
            if e.is_nan() { f64::INFINITY } else { e / scale }
        })
        .fold(0.0, f64::max)
}

#[test]
fn gpu_eigenvalues_are_within_the_bound_where_the_naive_form_fails() {
    let engine = common::engine();
    let probe = EigenProbe::new(engine.device(), ash::vk::PipelineCache::null()).unwrap();
    let mut rng = Rng(16);
    let mut cases: Vec<(String, [f32; 6])> = Vec::new();
    for (name, l) in hard_spectra() {
        for i in 0..20 {
            let q = rotation(&mut rng);
            cases.push((format!("{name} #{i}"), entries(&with_spectrum(l, &q))));
        }
        // Diagonal (no rotation): exact input, the sweeps must not disturb it.
        cases.push((
            format!("{name} diagonal"),
            entries(&with_spectrum(
                l,
                &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            )),
        ));
    }
    for i in 0..500 {
        let e = [0; 6].map(|_| rng.range(-1.0, 1.0) as f32);
        cases.push((format!("random #{i}"), e));
    }
    let matrices: Vec<[f32; 6]> = cases.iter().map(|c| c.1).collect();
    let out = probe.run(engine.device(), &matrices).unwrap();
    let mut worst = (0.0f64, String::new());
    let mut worst_naive_near = 0.0f64;
    let mut worst_naive_huge = 0.0f64;
    for ((name, e), r) in cases.iter().zip(&out) {
        let exact = sym3_eigenvalues(&from_f32(e));
        let x = excess(r.jacobi, exact);
        if x > worst.0 {
            worst = (x, format!("{name}: {:?} vs {exact:?}", r.jacobi));
        }
        let naive = excess(r.naive, exact);
        if name.starts_with("nearly") && !name.contains(" x ") {
            worst_naive_near = worst_naive_near.max(naive);
        }
        if name.contains("x 1e36") || name.contains("x 1e-36") {
            worst_naive_huge = worst_naive_huge.max(naive);
        }
    }
    println!(
        "worst GPU error: {:.3e} of the bound ({:.1e} |l|max) at {}",
        worst.0, GPU_REL_BOUND, worst.1
    );
    println!(
        "naive closed form: {worst_naive_near:.1e} x the bound on nearly repeated spectra, {worst_naive_huge:.1e} x on 1e+-36 magnitudes"
    );
    assert!(
        worst.0 <= 1.0,
        "GPU eigenvalues beyond the bound: {}",
        worst.1
    );
    // The bound separates the technique from the naive form on this device.
    assert!(
        worst_naive_near > 1.0,
        "naive form within the bound on nearly repeated spectra"
    );
    assert!(
        worst_naive_huge > 1.0,
        "naive form within the bound at 1e+-36"
    );
    common::assert_no_validation_errors(&engine);
}

#[test]
fn gpu_eigenvalues_of_non_finite_matrices_are_zero() {
    let engine = common::engine();
    let probe = EigenProbe::new(engine.device(), ash::vk::PipelineCache::null()).unwrap();
    let mut matrices = Vec::new();
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        for slot in 0..6 {
            let mut e = [1.0, 2.0, 3.0, 0.5, 0.25, 0.125];
            e[slot] = bad;
            matrices.push(e);
        }
    }
    let out = probe.run(engine.device(), &matrices).unwrap();
    for (m, r) in matrices.iter().zip(&out) {
        assert_eq!(r.jacobi, [0.0; 3], "{m:?}");
    }
    common::assert_no_validation_errors(&engine);
}
