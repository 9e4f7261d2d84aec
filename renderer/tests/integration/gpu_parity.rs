//! End-to-end parity: the wgpu rasterizer against the CPU reference (`cpu::render`) on real
//! wgpu (Mesa lavapipe in CI; a missing adapter fails, it never skips).
//!
//! Tolerance: both rasterizers composite the same Gaussians in the same order with the same
//! rules, so the images differ only by float rounding (GPU `exp`, division and fused
//! multiply-adds). Per pixel and channel: rgb, alpha and confidence within 2e-3 absolute;
//! depth, raw depth and surface depth within 2e-3 relative to max(1 m, CPU value). A pixel
//! whose float comparison at the 1/255 alpha, 1e-4 transmittance or one-half transmittance
//! (surface depth) threshold flips may exceed that: such pixels are counted and must stay under 0.1% of the image. The measured numbers are
//! printed (`cargo test --release -- --nocapture`).

use glam::{Quat, Vec3};
use renderer::camera::{Camera, Intrinsics};
use renderer::gaussians::{Gaussian, GaussianSet};
use renderer::gpu::GpuRasterizer;
use renderer::output::{RenderOutput, RenderSettings};
use renderer::{cpu, scene};

const ABS_TOL: f32 = 2e-3;
const MAX_OUTLIER_FRACTION: f64 = 1e-3;

fn rasterizer() -> GpuRasterizer {
    let gpu = GpuRasterizer::new().expect("a GPU adapter is required (CI installs Mesa lavapipe)");
    let info = gpu.adapter_info();
    println!("adapter: {} ({:?})", info.name, info.backend);
    gpu
}

/// `a` followed by the Gaussians of `b`.
fn concat(mut a: GaussianSet, b: &GaussianSet) -> GaussianSet {
    for i in 0..b.len() {
        a.push(b.get(i));
    }
    a
}

fn settings() -> RenderSettings {
    RenderSettings {
        background: [0.1, 0.2, 0.3],
        ..Default::default()
    }
}

/// Worst error per output and number of pixels beyond tolerance in any output.
struct Comparison {
    max_err: [f32; 6],
    outliers: usize,
}

fn compare(gpu: &RenderOutput, cpu: &RenderOutput) -> Comparison {
    assert_eq!((gpu.width, gpu.height), (cpu.width, cpu.height));
    let mut max_err = [0.0f32; 6];
    let mut outliers = 0;
    for p in 0..cpu.pixels() {
        let abs = |a: f32, b: f32| (a - b).abs();
        let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1.0);
        let errs = [
            (0..3)
                .map(|k| abs(gpu.rgb[3 * p + k], cpu.rgb[3 * p + k]))
                .fold(0.0, f32::max),
            abs(gpu.alpha[p], cpu.alpha[p]),
            abs(gpu.confidence[p], cpu.confidence[p]),
            rel(gpu.depth[p], cpu.depth[p]),
            rel(gpu.depth_raw[p], cpu.depth_raw[p]),
            rel(gpu.surface_depth[p], cpu.surface_depth[p]),
        ];
        if errs.iter().any(|&e| e.is_nan() || e > ABS_TOL) {
            outliers += 1;
        }
        for (m, e) in max_err.iter_mut().zip(errs) {
            *m = m.max(e);
        }
    }
    Comparison { max_err, outliers }
}

/// Renders on both rasterizers, prints the errors and checks the tolerance of the module.
fn check(gpu: &mut GpuRasterizer, name: &str, set: &GaussianSet, cam: &Camera) -> RenderOutput {
    let settings = settings();
    let out = gpu.render(set, cam, &settings).expect("GPU render");
    let reference = cpu::render(&set.view().unwrap(), &cam.params(), &settings).output;
    let c = compare(&out, &reference);
    println!(
        "{name}: {} Gaussians, {}x{}: max err rgb {:.2e} alpha {:.2e} confidence {:.2e} depth(rel) {:.2e} depth_raw(rel) {:.2e} surface_depth(rel) {:.2e}, {} outlier pixels",
        set.len(),
        out.width,
        out.height,
        c.max_err[0],
        c.max_err[1],
        c.max_err[2],
        c.max_err[3],
        c.max_err[4],
        c.max_err[5],
        c.outliers
    );
    assert!(
        (c.outliers as f64) <= MAX_OUTLIER_FRACTION * reference.pixels() as f64,
        "{name}: {} of {} pixels beyond tolerance",
        c.outliers,
        reference.pixels()
    );
    out
}

#[test]
fn random_scene_matches_the_cpu() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(320, 240, 70.0);
    check(
        &mut gpu,
        "random",
        &scene::random_in_view(1, 20_000, &k),
        &Camera::identity(k),
    );
}

/// A posed camera far from the origin (position-relative arithmetic, a real rotation).
#[test]
fn posed_camera_far_from_the_origin_matches_the_cpu() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(256, 160, 80.0);
    let mut set = concat(
        scene::small_overlapping(2, 400, &k),
        &scene::random_in_view(3, 5000, &k),
    );
    let q = Quat::from_euler(glam::EulerRot::YXZ, 1.1, 0.2, -0.05);
    let offset = Vec3::new(5200.0, -31.0, -870.0);
    for (m, r) in set.means.iter_mut().zip(&mut set.rotations) {
        *m = q * *m + offset;
        *r = q * *r;
    }
    check(
        &mut gpu,
        "posed",
        &set,
        &Camera::from_camera_to_world(k, q, offset),
    );
}

/// Dense and street-like: one pixel-aligned Gaussian per pixel of two stereo views at the
/// paper's input size (121,856 Gaussians).
#[test]
fn dense_street_scene_matches_the_cpu() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(544, 112, 90.0);
    check(
        &mut gpu,
        "street",
        &scene::pixel_aligned(4, &k, 2, 0.54),
        &Camera::identity(k),
    );
}

#[test]
fn everything_behind_the_camera_gives_the_background() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(64, 48, 60.0);
    let mut set = scene::random_in_view(5, 500, &k);
    set.means.iter_mut().for_each(|m| m.z = -m.z);
    let out = check(&mut gpu, "behind", &set, &Camera::identity(k));
    assert!(out.alpha.iter().all(|&a| a == 0.0));
    assert!(out.rgb.chunks(3).all(|c| c == settings().background));
}

#[test]
fn a_single_gaussian_matches_the_cpu() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(96, 64, 60.0);
    let mut set = GaussianSet::default();
    set.push(Gaussian {
        mean: Vec3::new(0.3, -0.1, 4.0),
        log_scale: Vec3::new(-1.5, -2.0, -2.5),
        rotation: Quat::from_rotation_z(0.7),
        opacity: 0.8,
        color: Vec3::new(0.9, 0.4, 0.1),
        confidence: 0.6,
    });
    let out = check(&mut gpu, "single", &set, &Camera::identity(k));
    assert!(out.alpha.iter().any(|&a| a > 0.5));
}

#[test]
fn an_empty_set_gives_the_background() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(40, 30, 60.0);
    let out = check(
        &mut gpu,
        "empty",
        &GaussianSet::default(),
        &Camera::identity(k),
    );
    assert!(out.rgb.chunks(3).all(|c| c == settings().background));
}

/// An image whose sides are not multiples of the 16-pixel tile.
#[test]
fn odd_image_size_matches_the_cpu() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(100, 37, 60.0);
    let set = concat(
        scene::small_overlapping(6, 300, &k),
        &scene::random_in_view(7, 2000, &k),
    );
    check(&mut gpu, "odd size", &set, &Camera::identity(k));
}

/// Sets whose arrays differ in length are rejected, not read out of bounds.
#[test]
fn a_ragged_set_is_an_error() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(32, 32, 60.0);
    let mut set = scene::random_in_view(8, 10, &k);
    set.opacities.pop();
    let err = gpu
        .render(&set, &Camera::identity(k), &settings())
        .unwrap_err();
    assert!(
        matches!(err, renderer::gpu::GpuError::LengthMismatch(_)),
        "{err}"
    );
}

/// Buffers are reused: after a first render, rendering the same scene again, and smaller
/// scenes and images, allocates no GPU buffer; a larger scene grows them once.
#[test]
fn repeated_renders_allocate_nothing() {
    let mut gpu = rasterizer();
    let k = Intrinsics::from_hfov(200, 120, 70.0);
    let cam = Camera::identity(k);
    let set = scene::random_in_view(9, 8000, &k);
    let first = gpu.render(&set, &cam, &settings()).unwrap();
    let after_first = gpu.buffer_allocations();
    for _ in 0..3 {
        assert_eq!(gpu.render(&set, &cam, &settings()).unwrap(), first);
    }
    let small_k = Intrinsics::from_hfov(64, 48, 70.0);
    gpu.render(
        &scene::random_in_view(10, 100, &small_k),
        &Camera::identity(small_k),
        &settings(),
    )
    .unwrap();
    gpu.render(&GaussianSet::default(), &cam, &settings())
        .unwrap();
    assert_eq!(
        gpu.buffer_allocations(),
        after_first,
        "steady state allocated buffers"
    );
    gpu.render(&scene::random_in_view(11, 40_000, &k), &cam, &settings())
        .unwrap();
    let grown = gpu.buffer_allocations();
    assert!(grown > after_first);
    gpu.render(&scene::random_in_view(11, 40_000, &k), &cam, &settings())
        .unwrap();
    assert_eq!(gpu.buffer_allocations(), grown);
}
