//! Each GPU stage against the CPU reference, on real wgpu (Mesa lavapipe in CI). A missing
//! adapter fails these tests: they never pass by skipping.

use glam::{Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::GpuRasterizer;
use crate::camera::{Camera, Intrinsics};
use crate::cpu::{self, Projected};
use crate::gaussians::{Gaussian, GaussianSet};
use crate::output::RenderSettings;
use crate::scene;

fn rasterizer() -> GpuRasterizer {
    GpuRasterizer::new().expect("a GPU adapter is required (CI installs Mesa lavapipe)")
}

/// `set` seen from `cam` moved rigidly (rotation `q` about the origin, then `offset`), with
/// the camera moved along: the image stays the same, the arithmetic gets a real pose.
fn posed(set: &GaussianSet, k: Intrinsics, q: Quat, offset: Vec3) -> (GaussianSet, Camera) {
    let mut moved = set.clone();
    for (m, r) in moved.means.iter_mut().zip(&mut moved.rotations) {
        *m = q * *m + offset;
        *r = q * *r;
    }
    (moved, Camera::from_camera_to_world(k, q, offset))
}

/// Random scene plus hand-made edge cases: behind the camera, beyond `far`, non-finite
/// parameters, a zero quaternion, a huge and a sub-pixel Gaussian, one far off screen.
fn projection_scene(k: &Intrinsics) -> GaussianSet {
    let mut set = scene::random_in_view(11, 4000, k);
    let base = set.get(0);
    let edit = |f: &dyn Fn(&mut Gaussian)| {
        let mut g = base;
        f(&mut g);
        g
    };
    let cases = [
        edit(&|g| g.mean.z = -g.mean.z),
        edit(&|g| g.mean.z = 2.0e10),
        edit(&|g| g.mean.x = f32::NAN),
        edit(&|g| g.log_scale.y = f32::INFINITY),
        edit(&|g| g.opacity = f32::NAN),
        edit(&|g| g.color.z = f32::NEG_INFINITY),
        edit(&|g| g.rotation = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)),
        edit(&|g| g.log_scale = Vec3::splat(3.0)),
        edit(&|g| g.log_scale = Vec3::splat(-12.0)),
        edit(&|g| g.mean.x = 40.0 * g.mean.z),
        edit(&|g| g.opacity = 1.7),
    ];
    for g in cases {
        set.push(g);
    }
    set
}

fn rel_err(gpu: f32, cpu: f32, scale: f32) -> f32 {
    (gpu - cpu).abs() / cpu.abs().max(scale)
}

/// Projection: same visibility; conic and depth within 1e-5 relative (conic relative to its
/// largest entry), mean2d within 5e-5 (lavapipe matches it exactly; NVIDIA's Vulkan
/// compiler fuses multiply-adds, and with the camera 1,200 m from the origin that moved
/// mean2d by 1.6e-5 on an H200, `results/gpu/`); radius and tile rectangle equal except
/// where `3 sqrt(lambda)` lands within rounding of an integer (counted, bounded to 0.1% of the Gaussians, radius off by
/// at most 1).
#[test]
fn projection_matches_the_cpu() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(320, 240, 70.0);
    let settings = RenderSettings::default();
    let base = projection_scene(&k);
    let q = Quat::from_euler(glam::EulerRot::YXZ, 0.4, -0.2, 0.1);
    for (set, cam) in [
        (base.clone(), Camera::identity(k)),
        posed(&base, k, q, Vec3::new(350.0, -20.0, 1200.0)),
    ] {
        let (projected, total) = gpu.probe_project(&set, &cam, &settings).unwrap();
        let view = set.view().unwrap();
        let params = cam.params::<f32>();
        let (mut radius_diffs, mut rect_diffs, mut visible) = (0, 0, 0);
        let mut worst = [0.0f32; 3];
        let mut expected_total = 0;
        for (i, g) in projected.iter().enumerate() {
            let c = cpu::project(&view, i, &params, &settings);
            assert_eq!(g.is_some(), c.is_some(), "visibility of Gaussian {i}");
            let (Some(g), Some(c)) = (g, c) else { continue };
            visible += 1;
            expected_total += g.tile_count();
            let conic_scale = c.conic.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            let errs = [
                rel_err(g.mean2d[0], c.mean2d[0], 1.0).max(rel_err(g.mean2d[1], c.mean2d[1], 1.0)),
                (0..3)
                    .map(|j| rel_err(g.conic[j], c.conic[j], conic_scale))
                    .fold(0.0, f32::max),
                rel_err(g.depth, c.depth, 1e-3),
            ];
            for (w, e) in worst.iter_mut().zip(errs) {
                *w = w.max(e);
            }
            assert_eq!((g.opacity, g.confidence), (c.opacity, c.confidence));
            if g.radius != c.radius {
                assert!(
                    (g.radius - c.radius).abs() <= 1.0,
                    "radius {} vs {}",
                    g.radius,
                    c.radius
                );
                radius_diffs += 1;
            }
            if (g.tile_min, g.tile_max) != (c.tile_min, c.tile_max) {
                rect_diffs += 1;
            }
        }
        println!("visible {visible}, worst rel err mean2d/conic/depth {worst:?}, radius diffs {radius_diffs}, rect diffs {rect_diffs}");
        assert!(visible > 3000);
        assert!(
            worst[0] <= 5e-5 && worst[1] <= 1e-5 && worst[2] <= 1e-5,
            "relative errors {worst:?}"
        );
        assert!(radius_diffs * 1000 <= visible && rect_diffs * 1000 <= visible);
        assert_eq!(total, expected_total, "intersection count read back");
    }
}

fn cpu_exclusive_scan(values: &[u32]) -> (Vec<u32>, u32) {
    let mut sum = 0u32;
    let scanned = values
        .iter()
        .map(|&v| {
            let before = sum;
            sum += v;
            before
        })
        .collect();
    (scanned, sum)
}

/// Prefix sum: exactly the CPU scan, for lengths around the block size, one and two levels
/// of recursion (100_000) and three (1_100_000).
#[test]
fn prefix_sum_matches_a_cpu_scan() {
    let mut gpu = rasterizer();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for n in [
        0usize, 1, 255, 256, 257, 1023, 1024, 1025, 100_000, 1_100_000,
    ] {
        let values: Vec<u32> = (0..n).map(|_| rng.random_range(0..1000)).collect();
        assert_eq!(
            gpu.probe_scan(&values).unwrap(),
            cpu_exclusive_scan(&values),
            "length {n}"
        );
    }
}

/// A total beyond `u32::MAX` saturates (so the caller reports the frame as too large)
/// instead of wrapping around to a small count.
#[test]
fn prefix_sum_total_saturates_instead_of_wrapping() {
    let mut gpu = rasterizer();
    let values = vec![u32::MAX / 3; 2000];
    assert_eq!(gpu.probe_scan(&values).unwrap().1, u32::MAX);
}

/// Radix sort: exactly a CPU stable sort by (tile, depth word), on random keys with many
/// ties (few distinct depths and tiles) and values that record the input order.
#[test]
fn radix_sort_matches_a_cpu_stable_sort() {
    let mut gpu = rasterizer();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for (n, tiles) in [
        (1usize, 1u32),
        (255, 3),
        (256, 17),
        (257, 1),
        (10_000, 300),
        (250_000, 8160),
    ] {
        let depths: Vec<u32> = (0..20).map(|_| rng.random()).collect();
        let keys: Vec<[u32; 2]> = (0..n)
            .map(|_| {
                [
                    depths[rng.random_range(0..depths.len())],
                    rng.random_range(0..tiles),
                ]
            })
            .collect();
        let values: Vec<u32> = (0..n as u32).collect();
        let mut expected: Vec<([u32; 2], u32)> =
            keys.iter().copied().zip(values.iter().copied()).collect();
        expected.sort_by_key(|&([depth, tile], _)| (tile, depth));
        let (sorted_keys, sorted_values) = gpu.probe_sort(&keys, &values, tiles).unwrap();
        let got: Vec<([u32; 2], u32)> = sorted_keys.into_iter().zip(sorted_values).collect();
        assert!(got == expected, "{n} keys on {tiles} tiles");
    }
}

/// Key generation, sort and tile ranges: per tile, exactly the lists `cpu::tiles::bin` makes
/// from the same (GPU) projection; and the same as binning the CPU's own projection.
#[test]
fn tile_lists_match_cpu_binning() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(200, 120, 70.0);
    let settings = RenderSettings::default();
    let cam = Camera::identity(k);
    let mut set = scene::random_in_view(3, 3000, &k);
    set.means.iter_mut().step_by(7).for_each(|m| m.z = 20.0); // equal depths: index order
    let (projected, lists) = gpu.probe_bins(&set, &cam, &settings).unwrap();
    let from_gpu_projection = cpu::tiles::bin(&projected, k.width, k.height);
    let view = set.view().unwrap();
    let cpu_projected: Vec<Option<Projected<f32>>> = (0..set.len())
        .map(|i| cpu::project(&view, i, &cam.params(), &settings))
        .collect();
    let from_cpu = cpu::tiles::bin(&cpu_projected, k.width, k.height);
    assert_eq!(lists.len(), from_cpu.tile_count());
    for (t, list) in lists.iter().enumerate() {
        assert_eq!(list.as_slice(), from_gpu_projection.tile(t), "tile {t}");
        assert_eq!(
            list.as_slice(),
            from_cpu.tile(t),
            "tile {t} vs the CPU projection"
        );
    }
}

/// Dispatches split into 2D grids (forced with a tiny per-dimension limit) compute the same
/// scan, sort and image as single-row ones.
#[test]
fn split_dispatches_give_the_same_results() {
    let mut gpu = rasterizer();
    gpu.set_max_groups_per_dimension(3);
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let values: Vec<u32> = (0..20_000).map(|_| rng.random_range(0..100)).collect();
    assert_eq!(
        gpu.probe_scan(&values).unwrap(),
        cpu_exclusive_scan(&values)
    );
    let keys: Vec<[u32; 2]> = (0..5000)
        .map(|_| [rng.random_range(0..50), rng.random_range(0..9)])
        .collect();
    let ids: Vec<u32> = (0..5000).collect();
    let (_, sorted) = gpu.probe_sort(&keys, &ids, 9).unwrap();
    let mut expected = ids.clone();
    expected.sort_by_key(|&i| (keys[i as usize][1], keys[i as usize][0]));
    assert_eq!(sorted, expected);
    let k = Intrinsics::from_hfov(48, 40, 60.0);
    let set = scene::random_in_view(4, 3000, &k);
    let cam = Camera::identity(k);
    let settings = RenderSettings::default();
    let out = gpu.render(&set, &cam, &settings).unwrap();
    let reference = cpu::render(&set.view().unwrap(), &cam.params(), &settings).output;
    let err = out
        .rgb
        .iter()
        .zip(&reference.rgb)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(err <= 2e-3, "max rgb error {err}");
}

/// The error converts into `anyhow::Error` (Send + Sync + 'static) and a rasterizer can move
/// to another thread.
#[test]
fn errors_and_the_rasterizer_cross_threads() {
    fn send_sync<T: Send + Sync + 'static>() {}
    send_sync::<super::GpuError>();
    send_sync::<GpuRasterizer>();
}

#[test]
fn a_profiled_frame_renders_the_same_images_and_names_its_stages_in_order() {
    let k = Intrinsics::from_hfov(160, 96, 70.0);
    let set = scene::random_in_view(3, 3000, &k);
    let cam = Camera::identity(k);
    let settings = RenderSettings::default();
    let mut gpu = rasterizer();
    let plain = gpu.render(&set, &cam, &settings).unwrap();
    for _ in 0..2 {
        let (out, profile) = gpu.render_profiled(&set, &cam, &settings).unwrap();
        assert_eq!(out.rgb, plain.rgb);
        assert_eq!(out.depth, plain.depth);
        let phases = [
            profile.upload_ms,
            profile.project_ms,
            profile.kernels_ms,
            profile.readback_ms,
        ];
        assert!(
            phases.iter().all(|t| t.is_finite() && *t >= 0.0),
            "{profile:?}"
        );
        assert!(phases.iter().sum::<f64>() > 0.0);
        // Stage timestamps where the adapter writes them (lavapipe may not): all seven.
        if !profile.stages.is_empty() {
            let names: Vec<_> = profile.stages.iter().map(|s| s.0).collect();
            let want = [
                "project",
                "prefix sum",
                "count read-back (gap)",
                "emit keys",
                "radix sort",
                "tile ranges",
                "composite",
            ];
            assert_eq!(names, want);
            assert!(profile.stages.iter().all(|s| s.1.is_finite() && s.1 >= 0.0));
        }
    }
    // A plain frame after profiled ones writes no marks and still matches.
    assert_eq!(gpu.render(&set, &cam, &settings).unwrap().rgb, plain.rgb);
}
