//! Surface depth: the depth of the Gaussian whose blend takes the accumulated opacity to
//! `surface_opacity` (else to one half), on the CPU rasterizer and the wgpu one (lavapipe in
//! CI). At an edge where a nearer surface half covers a farther one, the expected depth lies
//! between the two surfaces and the surface depth on one of them.

use glam::{Quat, Vec3};
use renderer::cpu::render;
use renderer::gpu::GpuRasterizer;
use renderer::{Camera, Gaussian, GaussianSet, Intrinsics, RenderOutput, RenderSettings};

const W: u32 = 32;
const H: u32 = 24;

fn cam() -> Camera {
    Camera::identity(Intrinsics::from_hfov(W, H, 60.0))
}

/// A wide Gaussian on the optical axis at depth `z` covering the whole image.
fn layer(z: f32, opacity: f32) -> Gaussian {
    Gaussian {
        mean: Vec3::new(0.0, 0.0, z),
        log_scale: Vec3::splat((10.0 * z).ln()),
        rotation: Quat::IDENTITY,
        opacity,
        color: Vec3::splat(0.5),
        confidence: 1.0,
    }
}

fn set_of(gs: &[Gaussian]) -> GaussianSet {
    let mut set = GaussianSet::default();
    gs.iter().for_each(|g| set.push(*g));
    set
}

fn cpu(gs: &[Gaussian]) -> RenderOutput {
    cpu_at(gs, 0.5)
}

fn cpu_at(gs: &[Gaussian], surface_opacity: f32) -> RenderOutput {
    let set = set_of(gs);
    let settings = RenderSettings {
        surface_opacity,
        ..Default::default()
    };
    render(&set.view().unwrap(), &cam().params(), &settings).output
}

/// The centre pixel.
const P: usize = (H / 2 * W + W / 2) as usize;

#[test]
fn a_nearer_surface_over_half_the_opacity_gives_its_own_depth() {
    // 0.8 at 1 m over 0.8 at 5 m: the front layer takes transmittance from 1 to about 0.2.
    let o = cpu(&[layer(1.0, 0.8), layer(5.0, 0.8)]);
    assert!(
        (o.surface_depth[P] - 1.0).abs() < 1e-6,
        "{}",
        o.surface_depth[P]
    );
    // The expected depth (0.8 * 1 + 0.16 * 5) / 0.96 = 1.67 m is on neither surface.
    assert!((o.depth[P] - 1.667).abs() < 0.01, "{}", o.depth[P]);
}

#[test]
fn a_faint_nearer_surface_gives_the_farther_depth() {
    // 0.3 at 1 m leaves 0.7; the 0.8 layer at 5 m takes it to 0.14, past one half.
    let o = cpu(&[layer(1.0, 0.3), layer(5.0, 0.8)]);
    assert!(
        (o.surface_depth[P] - 5.0).abs() < 1e-5,
        "{}",
        o.surface_depth[P]
    );
    assert!(o.depth[P] > 1.0 && o.depth[P] < 5.0);
}

#[test]
fn a_pixel_under_half_covered_has_no_surface_depth() {
    let o = cpu(&[layer(2.0, 0.4)]);
    assert!(o.alpha[P] < 0.5);
    assert_eq!(o.surface_depth[P], 0.0);
    assert!((o.depth[P] - 2.0).abs() < 1e-5);
    // Nothing at all: no depth of either kind.
    let empty = cpu(&[]);
    assert!(empty.surface_depth.iter().all(|&d| d == 0.0));
}

#[test]
fn exactly_one_half_counts_as_reached() {
    // Two layers of 1 - sqrt(0.5) each: the second takes transmittance to 0.5 (rounding may
    // leave it a hair above, then the crossing is the third layer at the same depth).
    let a = 1.0 - 0.5f32.sqrt();
    let o = cpu(&[layer(1.0, a), layer(2.0, a), layer(2.0, 0.9)]);
    assert!(
        (o.surface_depth[P] - 2.0).abs() < 1e-5,
        "{}",
        o.surface_depth[P]
    );
}

#[test]
fn a_higher_opacity_passes_over_a_nearer_fringe() {
    // 0.8 at 1 m leaves 0.2 of the light; 0.8 at 5 m leaves 0.04: the opacity reaches 0.95
    // on the farther layer.
    let two = [layer(1.0, 0.8), layer(5.0, 0.8)];
    assert!((cpu_at(&two, 0.95).surface_depth[P] - 5.0).abs() < 1e-5);
    assert!((cpu_at(&two, 0.7).surface_depth[P] - 1.0).abs() < 1e-6);
    // A pixel that never reaches the opacity keeps the median: 0.8 alone stops at 0.8.
    assert!((cpu_at(&[layer(2.0, 0.8)], 0.95).surface_depth[P] - 2.0).abs() < 1e-5);
}

#[test]
fn out_of_range_opacities_fall_back_to_the_median() {
    // At 1 or above, at 0 or below (the opacity starts there) and at NaN the opacity is
    // never crossed: the median.
    let two = [layer(1.0, 0.8), layer(5.0, 0.8)];
    for level in [
        1.0,
        7.0,
        f32::INFINITY,
        0.0,
        -3.0,
        f32::NEG_INFINITY,
        f32::NAN,
    ] {
        let o = cpu_at(&two, level);
        assert!(
            (o.surface_depth[P] - 1.0).abs() < 1e-6,
            "{level}: {}",
            o.surface_depth[P]
        );
    }
}

#[test]
fn the_gpu_gives_the_same_surface_depth() {
    let mut gpu =
        GpuRasterizer::new().expect("a GPU adapter is required (CI installs Mesa lavapipe)");
    for gs in [
        vec![layer(1.0, 0.8), layer(5.0, 0.8)],
        vec![layer(1.0, 0.3), layer(5.0, 0.8)],
        vec![layer(2.0, 0.4)],
        vec![layer(2.0, 0.8)],
    ] {
        for surface_opacity in [0.5, 0.7, 0.95, 7.0] {
            let settings = RenderSettings {
                surface_opacity,
                ..Default::default()
            };
            let g = gpu.render(&set_of(&gs), &cam(), &settings).unwrap();
            let c = cpu_at(&gs, surface_opacity);
            for (a, b) in g.surface_depth.iter().zip(&c.surface_depth) {
                assert!((a - b).abs() <= 1e-4 * b.max(1.0), "gpu {a} cpu {b}");
            }
        }
    }
}
