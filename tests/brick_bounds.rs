//! The brick-bounds pass (shaders/brick_bounds.comp) against its f64 twin
//! (`BrickRanges::reference_bits`, `reference_bounds`): bits equal exactly, bounds no lower than
//! the twin's minus 1e-6 and within 1e-5, at brick grids that are not multiples of the
//! workgroup or of 32, with the vessel channel and labels on and off, and at ranges placed on
//! the window supports' f32 neighbours, where a rounding error would flip a bit. The distance
//! map made from the bits (shaders/brick_distance.comp) equals its twin
//! (`reference::brick_distance`) exactly, on the same grids and on sparse patterns made to reach
//! far: single bricks, corners, lines longer than the 255 cap, nothing occupied.

mod common;

use morphray::analysis::Window;
use morphray::reference::brick_distance::{FAR, chebyshev_distances};
use morphray::scene::occupancy::{BrickRanges, bound_channels, reference_ranges};
use morphray::scene::{Classification, TissueClass};
use std::sync::Arc;

/// A deterministic pseudo-random I_norm volume: smooth blobs plus noise, some zero background.
fn volume(dims: [u32; 3], seed: u32) -> Vec<f64> {
    let mut state = seed.wrapping_mul(2654435761).wrapping_add(12345);
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        f64::from(state >> 8) / f64::from(1u32 << 24)
    };
    let n = (dims[0] * dims[1] * dims[2]) as usize;
    (0..n)
        .map(|i| {
            let x = (i % dims[0] as usize) as f64 / dims[0] as f64;
            let base = if x < 0.2 { 0.0 } else { 0.6 * x };
            (base + 0.2 * next()).min(1.0)
        })
        .collect()
}

fn classifications() -> Vec<Classification> {
    let window = |lo, hi, edge| Some(Window { lo, hi, edge });
    let mut all = Classification::with_windows([
        window(0.05, 0.12, 0.01),
        window(0.3, 0.45, 0.02),
        window(0.6, 0.7, 0.05),
        window(0.85, 0.95, 0.0),
    ]);
    all.show_only(&TissueClass::ALL);
    let mut default = all;
    default.style_mut(TissueClass::Pathology).visible = false;
    let mut narrow = Classification::with_windows([window(0.71, 0.7101, 1e-5), None, None, None]);
    narrow.style_mut(TissueClass::Csf).opacity = 0.37;
    let mut none = default;
    none.show_only(&[]);
    let mut zero_opacity = default;
    zero_opacity.style_mut(TissueClass::Gm).opacity = 0.0;
    zero_opacity.style_mut(TissueClass::Wm).opacity = 2.0;
    zero_opacity.vessels.opacity = 0.0;
    vec![all, default, narrow, none, zero_opacity]
}

/// Label bits with every fifth brick set.
fn labels(bricks: usize) -> Arc<Vec<u32>> {
    let mut bits = vec![0u32; bricks.div_ceil(32).max(1)];
    for b in (0..bricks).step_by(5) {
        bits[b / 32] |= 1 << (b % 32);
    }
    Arc::new(bits)
}

fn check(
    engine: &mut morphray::engine::Engine,
    ranges: &Arc<BrickRanges>,
    vessels: Option<&Arc<BrickRanges>>,
    labels: Option<&Arc<Vec<u32>>>,
    what: &str,
) {
    for (i, c) in classifications().iter().enumerate() {
        let gpu = engine.brick_bounds(ranges, c, vessels, labels).unwrap();
        let v = vessels.map(|v| v.as_ref());
        let l = labels.map(|l| l.as_slice());
        let bits = ranges.reference_bits(c, v, l);
        assert_eq!(gpu.bits, bits, "{what}, classification {i}");
        let distances = chebyshev_distances(&bits, ranges.grid);
        assert_eq!(gpu.distances, distances, "{what}, classification {i}");
        let twin = ranges.reference_bounds(c, v, l);
        assert_eq!(gpu.bounds.len(), twin.len());
        for (b, (&g, &t)) in gpu.bounds.iter().zip(&twin).enumerate() {
            let g = f64::from(g);
            assert!(
                g >= t - 1e-6 && (g - t).abs() <= 1e-5,
                "{what}, classification {i}, brick {b}: GPU {g}, twin {t}"
            );
        }
        let set: u32 = bits.iter().map(|w| w.count_ones()).sum();
        let expected = f64::from(set) / ranges.ranges.len() as f64;
        assert_eq!(gpu.occupied, expected, "{what}, classification {i}");
    }
}

#[test]
fn gpu_bits_and_bounds_equal_the_twin_at_awkward_sizes() {
    let mut engine = common::engine();
    for (k, dims) in [[23, 19, 17], [9, 14, 7], [8, 8, 8], [1, 1, 1], [70, 33, 41]]
        .into_iter()
        .enumerate()
    {
        let ranges = Arc::new(reference_ranges(&volume(dims, k as u32), dims, 8));
        let vesselness = Arc::new(reference_ranges(&volume(dims, 100 + k as u32), dims, 8));
        let bricks = ranges.ranges.len();
        let l = labels(bricks);
        check(&mut engine, &ranges, None, None, &format!("{dims:?}"));
        check(
            &mut engine,
            &ranges,
            Some(&vesselness),
            None,
            &format!("{dims:?} vessels"),
        );
        check(
            &mut engine,
            &ranges,
            None,
            Some(&l),
            &format!("{dims:?} labels"),
        );
        check(
            &mut engine,
            &ranges,
            Some(&vesselness),
            Some(&l),
            &format!("{dims:?} both"),
        );
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn bits_at_the_supports_f32_neighbours_equal_the_twin() {
    // Every brick's range ends (or starts) one f32 step around a support bound: the host's
    // outward rounding must make the GPU's f32 test decide exactly as the f64 test.
    let mut engine = common::engine();
    for c in classifications() {
        let mut ends = Vec::new();
        for channel in bound_channels(&c, false).into_iter().flatten() {
            for s in [channel.support.0, channel.support.1] {
                ends.extend([s.next_down(), s, s.next_up()]);
            }
        }
        let mut pairs = Vec::new();
        for &e in &ends {
            let e = e.clamp(0.0, 1.0);
            pairs.push((0.0, e)); // maximum at the bound
            pairs.push((e, 1.0)); // minimum at the bound
            pairs.push((e, e));
        }
        if pairs.is_empty() {
            continue;
        }
        let n = pairs.len() as u32;
        let ranges = Arc::new(BrickRanges {
            grid: [n, 1, 1],
            side: 8,
            ranges: pairs,
        });
        check(&mut engine, &ranges, None, None, "support neighbours");
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn the_bound_covers_every_value_in_the_brick() {
    // The twin's bound is an upper bound of f(v) for every v in the brick's range (checked on a
    // fine grid of v), and it is tight where the range holds the window's peak.
    let ranges = BrickRanges {
        grid: [4, 1, 1],
        side: 8,
        ranges: vec![(0.0, 0.28), (0.31, 0.33), (0.5, 0.55), (0.0, 1.0)],
    };
    for c in classifications() {
        let bounds = ranges.reference_bounds(&c, None, None);
        for (b, &(lo, hi)) in ranges.ranges.iter().enumerate() {
            for i in 0..=1000 {
                let v = f64::from(lo) + (f64::from(hi) - f64::from(lo)) * f64::from(i) / 1000.0;
                let (f, _) = c.classify(v);
                assert!(
                    f <= bounds[b] + 1e-12,
                    "brick {b}, v {v}: f {f} > {}",
                    bounds[b]
                );
            }
        }
    }
}

#[test]
fn the_pass_runs_when_the_classification_changes_never_per_frame() {
    use ash::vk;
    use morphray::volume::phantom::{PhantomSpec, generate};
    let mut engine = common::engine();
    let volume = generate(&PhantomSpec::cube(24)).unwrap().volume;
    let prepared = engine.prepare(&volume).unwrap();
    let window = |lo, hi| Some(Window { lo, hi, edge: 0.01 });
    let mut scene = morphray::scene::Scene::new(Classification::with_windows([
        window(0.1, 0.3),
        window(0.4, 0.6),
        None,
        None,
    ]));
    scene.effects.mode = morphray::scene::RenderMode::Dvr;
    let derived = engine
        .derive(&prepared, scene.effects.derivative_outputs().unwrap())
        .unwrap();
    let mut target = engine
        .render_target(16, 16, vk::Format::R8G8B8A8_UNORM)
        .unwrap();
    let runs = |e: &morphray::engine::Engine| e.counters().brick_bounds_runs;
    let mut frame = |engine: &mut morphray::engine::Engine, scene: &morphray::scene::Scene| {
        engine
            .render(&mut target, &prepared, Some(&derived), scene)
            .unwrap();
    };
    let start = runs(&engine);
    // Two frames in flight: one run per slot.
    frame(&mut engine, &scene);
    frame(&mut engine, &scene);
    assert_eq!(runs(&engine), start + 2);
    // An orbit runs nothing.
    for i in 0..6 {
        scene.camera.azimuth_deg = 30.0 * f64::from(i);
        frame(&mut engine, &scene);
    }
    assert_eq!(runs(&engine), start + 2);
    // A tissue toggle runs it again, once per slot.
    scene.classification.show_only(&[TissueClass::Gm]);
    for _ in 0..4 {
        frame(&mut engine, &scene);
    }
    assert_eq!(runs(&engine), start + 4);
    common::assert_no_validation_errors(&engine);
}

/// Ranges that make exactly the bricks `occupied` visible under [`sparse_classification`].
fn sparse_ranges(grid: [u32; 3], occupied: &[usize]) -> Arc<BrickRanges> {
    let count = (grid[0] * grid[1] * grid[2]) as usize;
    let mut ranges = vec![(0.0f32, 0.0f32); count];
    for &b in occupied {
        ranges[b] = (0.5, 0.55);
    }
    Arc::new(BrickRanges {
        grid,
        side: 8,
        ranges,
    })
}

fn sparse_classification() -> Classification {
    let window = Some(Window {
        lo: 0.45,
        hi: 0.6,
        edge: 0.01,
    });
    let mut c = Classification::with_windows([None, None, window, None]);
    c.show_only(&[TissueClass::Wm]);
    c
}

#[test]
fn distance_map_equals_the_twin_on_sparse_far_reaching_patterns() {
    let mut engine = common::engine();
    let c = sparse_classification();
    let mut state = 7u32;
    let mut next = |n: usize| {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as usize % n
    };
    let mut cases: Vec<([u32; 3], Vec<usize>)> = vec![
        ([1, 1, 1], vec![]),
        ([1, 1, 1], vec![0]),
        ([13, 7, 5], vec![]),
        ([13, 7, 5], vec![0]),
        ([13, 7, 5], vec![13 * 7 * 5 - 1]),
        ([300, 1, 1], vec![0]),
        ([1, 2, 290], vec![1]),
        ([9, 300, 1], vec![4 + 9 * 150]),
    ];
    for grid in [[17, 11, 6], [33, 5, 9], [4, 4, 4], [70, 3, 2]] {
        let count = (grid[0] * grid[1] * grid[2]) as usize;
        for occupied in [1, 3, count / 50 + 1] {
            let set = (0..occupied).map(|_| next(count)).collect();
            cases.push((grid, set));
        }
    }
    for (grid, occupied) in cases {
        let ranges = sparse_ranges(grid, &occupied);
        let gpu = engine.brick_bounds(&ranges, &c, None, None).unwrap();
        let twin = chebyshev_distances(&gpu.bits, grid);
        let set: usize = gpu.bits.iter().map(|w| w.count_ones() as usize).sum();
        let mut unique = occupied.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(set, unique.len(), "{grid:?}: the pattern's bits");
        assert_eq!(gpu.distances, twin, "{grid:?}, occupied {occupied:?}");
        if occupied.is_empty() {
            assert!(gpu.distances.iter().all(|&d| d == FAR), "{grid:?}");
        }
    }
    common::assert_no_validation_errors(&engine);
}
