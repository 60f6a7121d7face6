//! The slice kernel (shaders/slice.comp) against its f64 twin (reference::slice) on awkward
//! volumes: odd dimensions, anisotropic spacing, an oblique flipped affine; every plane, both
//! conventions, a pixel size that matches no voxel, a position between voxels. Zero
//! validation-layer errors.

mod common;

use common::volumes::{Rng, smooth_field, volume, volume_with_affine};
use morphray::engine::readback::read_image;
use morphray::engine::slice::{Slicer, geometry_of};
use morphray::gpu::Access;
use morphray::reference;
use morphray::scene::slice::{Convention, Plane, SliceGrid, centre_position};
use morphray::volume::{Samples, Volume};

/// Slices `v` in every plane and convention and compares each pixel with the twin.
fn check_slices(engine: &mut morphray::engine::Engine, v: &Volume, pixel_mm: f64) {
    let prepared = engine.prepare(v).unwrap();
    let norm = read_image(
        engine.device(),
        &prepared.normalized,
        Access::ComputeSampled,
    )
    .unwrap();
    let values: Vec<f64> = norm.values.iter().map(|&x| x as f64).collect();
    let geometry = geometry_of(&prepared).unwrap();
    let slicer = Slicer::new(engine).unwrap();
    let window = (0.2, 0.85);
    for plane in Plane::ALL {
        for convention in [Convention::Radiological, Convention::Neurological] {
            // Between voxel centres on purpose: interpolation along the normal too.
            let position = centre_position(&geometry, plane) + 0.37;
            let grid = SliceGrid::new(&geometry, plane, convention, position, pixel_mm).unwrap();
            let image = slicer.render(engine, &prepared, &grid, window).unwrap();
            let index = grid.in_index_space(&geometry);
            let (w, h) = (grid.width as usize, grid.height as usize);
            let twin = reference::slice::slice(
                &values,
                v.dims,
                index.origin,
                index.du,
                index.dv,
                w,
                h,
                window,
            )
            .unwrap();
            assert_eq!(image.rgba8.len(), w * h * 4);
            let (mut inside, mut bright) = (0, 0);
            for (n, want) in twin.iter().enumerate() {
                let (x, y) = ((n % w) as f64, (n / w) as f64);
                let p: [f64; 3] =
                    std::array::from_fn(|a| index.origin[a] + x * index.du[a] + y * index.dv[a]);
                // Within f32 rounding of the box's faces inside/outside is a coin toss.
                let near_face = (0..3).any(|a| {
                    (p[a] + 0.5).abs() < 1e-3 || (p[a] - (v.dims[a] as f64 - 0.5)).abs() < 1e-3
                });
                if near_face {
                    continue;
                }
                let px = &image.rgba8[4 * n..4 * n + 4];
                let is_inside = reference::slice::sample(&values, v.dims, p).is_some();
                assert_eq!(
                    px[3],
                    if is_inside { 255 } else { 0 },
                    "alpha at {n}, {plane:?}"
                );
                let got = px[0] as f64 / 255.0;
                assert!(
                    (got - want).abs() <= 0.6 / 255.0,
                    "{plane:?} {convention:?} pixel ({x}, {y}) of {w}x{h}: GPU {got}, twin {want}"
                );
                assert!(px[0] == px[1] && px[1] == px[2], "grey");
                inside += is_inside as usize;
                bright += (px[0] > 0 && px[0] < 255) as usize;
            }
            assert!(
                inside > w * h / 4,
                "{plane:?}: too few pixels inside ({inside})"
            );
            assert!(bright > 0, "{plane:?}: no grey between black and white");
        }
    }
}

#[test]
fn slices_match_the_twin_on_anisotropic_and_oblique_volumes() {
    let mut engine = common::engine();
    let mut rng = Rng(16);
    let dims = [17usize, 13, 11];
    let field = smooth_field(dims, &mut rng, 0.0, 1000.0);
    let samples = Samples::from_u16(&field.iter().map(|&x| x as u16).collect::<Vec<_>>());
    check_slices(&mut engine, &volume(dims, [0.7, 1.0, 2.3], samples), 0.61);
    let dims = [9usize, 14, 7];
    let field = smooth_field(dims, &mut rng, -300.0, 900.0);
    let samples = Samples::from_f32(&field.iter().map(|&x| x as f32).collect::<Vec<_>>());
    // Oblique: 25 degrees about z and 15 about x, anisotropic, x flipped, an origin.
    let (cz, sz) = (25f64.to_radians().cos(), 25f64.to_radians().sin());
    let (cx, sx) = (15f64.to_radians().cos(), 15f64.to_radians().sin());
    let r = [
        [cz, -sz * cx, sz * sx],
        [sz, cz * cx, -cz * sx],
        [0.0, sx, cx],
    ];
    let s = [-0.9, 1.1, 1.7];
    let mut affine = [[0.0; 4]; 4];
    for (row, r_row) in r.iter().enumerate() {
        for col in 0..3 {
            affine[row][col] = r_row[col] * s[col];
        }
    }
    affine[0][3] = 12.0;
    affine[1][3] = -7.0;
    affine[2][3] = 3.5;
    affine[3][3] = 1.0;
    check_slices(
        &mut engine,
        &volume_with_affine(dims, affine, samples),
        0.53,
    );
    common::assert_no_validation_errors(&engine);
}

#[test]
fn a_voxel_aligned_slice_reproduces_the_voxels_exactly() {
    // A 5x4x3 volume at 1 x 2 x 3 mm sliced at 1 mm: every column is a voxel centre, every
    // third row too; the others interpolate.
    let mut engine = common::engine();
    let dims = [5usize, 4, 3];
    let stored: Vec<u8> = (0..60).map(|n| (n * 4) as u8).collect();
    let v = volume(dims, [1.0, 2.0, 3.0], Samples::from_u8(stored.clone()));
    let prepared = engine.prepare(&v).unwrap();
    let geometry = geometry_of(&prepared).unwrap();
    let slicer = Slicer::new(&engine).unwrap();
    // Coronal through voxel row j = 2 (y = 4 mm); neurological, so columns run along +x.
    let grid = SliceGrid::new(
        &geometry,
        Plane::Coronal,
        Convention::Neurological,
        4.0,
        1.0,
    )
    .unwrap();
    assert_eq!((grid.width, grid.height), (5, 9));
    let image = slicer
        .render(&engine, &prepared, &grid, (0.0, 1.0))
        .unwrap();
    let mut checked = 0;
    for (n, px) in image.rgba8.chunks_exact(4).enumerate() {
        let world = grid.world_of_pixel((n % 5) as f64, (n / 5) as f64);
        let (i, k) = (world.x, world.z / 3.0);
        if (k - k.round()).abs() < 1e-9 {
            let voxel = stored[i.round() as usize + 5 * (2 + 4 * k.round() as usize)];
            // I_norm = stored / 236 (min/max normalization), then 8 bits.
            let want = (voxel as f64 / 236.0 * 255.0).round() as i32;
            assert!(
                (px[0] as i32 - want).abs() <= 1,
                "voxel ({i}, 2, {k}): {} vs {want}",
                px[0]
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 15, "three rows of five voxel centres");
    common::assert_no_validation_errors(&engine);
}
