//! The self-check on a textured plane seen by a rectified pair, where the true depth is
//! known: right geometry passes, wrong geometry or a wrong image fails, flat images are
//! undetermined, and no input makes a NaN or an unbounded cost.

use glam::{Mat3, Quat, Vec3};
use renderer::{Camera, Gaussian, GaussianSet, Intrinsics};

use super::*;
use crate::frame::RgbImage;

const W: u32 = 272;
const H: u32 = 72;
const BASELINE: f32 = 0.5;
/// Disparity of the plane in pixels.
const DISPARITY: u32 = 12;

fn intrinsics() -> Intrinsics {
    Intrinsics {
        fx: 240.0,
        fy: 240.0,
        cx: 136.0,
        cy: 36.0,
        width: W,
        height: H,
    }
}

fn cameras() -> (Camera, Camera) {
    let left = Camera::identity(intrinsics());
    let right = Camera {
        position: Vec3::new(BASELINE, 0.0, 0.0),
        rotation: Mat3::IDENTITY,
        ..left
    };
    (left, right)
}

/// A blocky random texture, value of texel (x, y) for `seed`.
fn texel(x: u32, y: u32, seed: u32) -> f32 {
    let mut h = (x / 2).wrapping_mul(0x9E37_79B1) ^ (y / 2).wrapping_mul(0x85EB_CA77) ^ seed;
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 13;
    (h % 1000) as f32 / 1000.0
}

/// An image of the texture of `seed` seen `shift` texels to the right.
fn image(shift: u32, seed: u32) -> RgbImage {
    let mut img = RgbImage::new(W, H);
    for y in 0..H {
        for x in 0..W {
            let v = texel(x + shift, y, seed);
            let i = 3 * (y * W + x) as usize;
            img.data[i..i + 3].copy_from_slice(&[v, 0.8 * v + 0.1, v]);
        }
    }
    img
}

/// One opaque Gaussian per left pixel on the plane at `depth`.
fn plane(depth: f32) -> GaussianSet {
    let k = intrinsics();
    let mut set = GaussianSet::default();
    for v in 0..H {
        for u in 0..W {
            set.push(Gaussian {
                mean: Vec3::new(
                    (u as f32 - k.cx) * depth / k.fx,
                    (v as f32 - k.cy) * depth / k.fy,
                    depth,
                ),
                log_scale: Vec3::splat(-4.0),
                rotation: Quat::IDENTITY,
                opacity: 1.0,
                color: Vec3::splat(0.5),
                confidence: 1.0,
            });
        }
    }
    set
}

fn true_depth() -> f32 {
    intrinsics().fx * BASELINE / DISPARITY as f32
}

fn run(left: &RgbImage, right: &RgbImage, set: &GaussianSet) -> CheckReport {
    let (left_camera, right_camera) = cameras();
    let view = StereoView {
        left,
        right,
        left_camera,
        right_camera,
    };
    let r = check(&view, set, &CheckSettings::default());
    assert!(
        r.score.is_finite() && (0.0..=1.0).contains(&r.score),
        "{r:?}"
    );
    assert!(
        r.coverage.is_finite() && (0.0..=1.0).contains(&r.coverage),
        "{r:?}"
    );
    r
}

#[test]
fn the_true_plane_passes_with_every_sample_consistent() {
    let r = run(&image(0, 1), &image(DISPARITY, 1), &plane(true_depth()));
    assert_eq!(r.verdict, Verdict::Pass, "{r:?}");
    // 68 x 18 cells of 4 px; those whose right patch leaves the image count as failures.
    assert!(r.samples > 900, "{r:?}");
    assert!(r.score > 0.9 && r.coverage > 0.99, "{r:?}");
}

#[test]
fn wrong_depth_wrong_scene_and_swapped_images_fail() {
    let depth = true_depth();
    let (left, right) = (image(0, 1), image(DISPARITY, 1));
    for (what, l, r, set) in [
        ("half depth", &left, &right, plane(0.5 * depth)),
        ("double depth", &left, &right, plane(2.0 * depth)),
        ("another scene", &left, &image(DISPARITY, 2), plane(depth)),
        ("swapped", &right, &left, plane(depth)),
    ] {
        let rep = run(l, r, &set);
        assert_eq!(rep.verdict, Verdict::Fail, "{what}: {rep:?}");
        assert!(rep.score < 0.2, "{what}: {rep:?}");
    }
}

#[test]
fn an_empty_reconstruction_of_a_textured_pair_fails_on_coverage() {
    let r = run(&image(0, 1), &image(DISPARITY, 1), &GaussianSet::default());
    assert_eq!((r.verdict, r.samples, r.score), (Verdict::Fail, 0, 0.0));
    assert!(r.textured > 900);
}

#[test]
fn black_white_and_tiny_images_are_undetermined() {
    let set = plane(true_depth());
    let black = RgbImage::new(W, H);
    let mut white = RgbImage::new(W, H);
    white.data.fill(1.0);
    let mut overexposed = RgbImage::new(W, H);
    overexposed.data.fill(f32::INFINITY);
    for (what, img) in [("black", &black), ("white", &white), ("inf", &overexposed)] {
        let r = run(img, img, &set);
        assert_eq!(r.verdict, Verdict::Undetermined, "{what}: {r:?}");
        assert_eq!((r.samples, r.textured, r.score), (0, 0, 0.0), "{what}");
    }
    let tiny = RgbImage::new(3, 3);
    let r = run(&tiny, &tiny, &set);
    assert_eq!((r.verdict, r.samples), (Verdict::Undetermined, 0));
}

#[test]
fn degenerate_gaussians_are_skipped_without_nan() {
    let mut set = plane(true_depth());
    let n = set.len();
    for i in (0..n).step_by(3) {
        set.means[i] = match i % 4 {
            0 => Vec3::NAN,
            1 => Vec3::new(0.0, 0.0, -5.0),
            2 => Vec3::new(1e30, 0.0, 1e-30),
            _ => Vec3::ZERO,
        };
    }
    set.opacities[1] = f32::NAN;
    set.opacities.truncate(n - 10);
    let r = run(&image(0, 1), &image(DISPARITY, 1), &set);
    assert_eq!(r.verdict, Verdict::Pass, "{r:?}");
}

#[test]
fn a_huge_set_is_strided_to_the_bound() {
    // 60 copies of the plane (1.18 M Gaussians) are visited at most 2^20 times: strided,
    // the verdict is the same.
    let one = plane(true_depth());
    let copies = 60;
    let huge = GaussianSet {
        means: one.means.repeat(copies),
        log_scales: one.log_scales.repeat(copies),
        rotations: one.rotations.repeat(copies),
        opacities: one.opacities.repeat(copies),
        colors: one.colors.repeat(copies),
        confidences: one.confidences.repeat(copies),
    };
    assert!(huge.len() > CheckSettings::default().max_gaussians);
    let r = run(&image(0, 1), &image(DISPARITY, 1), &huge);
    assert_eq!(r.verdict, Verdict::Pass, "{r:?}");
}
