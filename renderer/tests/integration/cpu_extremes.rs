//! Numerical extremes on the CPU rasterizer: every output and gradient stays finite, and each
//! degenerate input follows its documented rule (see `cpu::project`'s culling rules).

use glam::{Quat, Vec3};
use renderer::cpu::{backward, render, OutputGrads, MAX_ALPHA};
use renderer::{Camera, Gaussian, GaussianSet, Intrinsics, RenderOutput, RenderSettings};

const W: u32 = 48;
const H: u32 = 32;

fn cam() -> Camera {
    Camera::identity(Intrinsics::from_hfov(W, H, 90.0))
}

/// A point at depth `z` that projects exactly onto the centre of pixel (W/2, H/2).
fn on_pixel(z: f32) -> Vec3 {
    let k = cam().intrinsics;
    Vec3::new(
        (W as f32 / 2.0 - k.cx) / k.fx * z,
        (H as f32 / 2.0 - k.cy) / k.fy * z,
        z,
    )
}

fn gaussian(mean: Vec3, scale: f32) -> Gaussian {
    Gaussian {
        mean,
        log_scale: Vec3::splat(scale.ln()),
        rotation: Quat::IDENTITY,
        opacity: 0.8,
        color: Vec3::new(1.0, 0.5, 0.25),
        confidence: 0.7,
    }
}

fn set_of(gs: &[Gaussian]) -> GaussianSet {
    let mut set = GaussianSet::default();
    gs.iter().for_each(|g| set.push(*g));
    set
}

/// Renders with a grey background, runs the backward pass with all-ones output gradients, and
/// asserts everything is finite. Returns the output and the largest gradient magnitude.
fn render_checked(set: &GaussianSet, cam: &Camera) -> (RenderOutput, f32) {
    let settings = RenderSettings {
        background: [0.5; 3],
        ..Default::default()
    };
    let view = set.view().unwrap();
    let params = cam.params::<f32>();
    let fwd = render(&view, &params, &settings);
    let o = &fwd.output;
    for (name, v) in [
        ("rgb", &o.rgb),
        ("depth", &o.depth),
        ("depth_raw", &o.depth_raw),
        ("alpha", &o.alpha),
        ("confidence", &o.confidence),
        ("surface_depth", &o.surface_depth),
    ] {
        assert!(
            v.iter().all(|x| x.is_finite()),
            "{name} has a non-finite value"
        );
    }
    let ones3 = vec![1.0f32; o.rgb.len()];
    let ones = vec![1.0f32; o.alpha.len()];
    let grads = OutputGrads {
        rgb: Some(&ones3),
        depth: Some(&ones),
        depth_raw: Some(&ones),
        alpha: Some(&ones),
        confidence: Some(&ones),
    };
    let g = backward(&view, &params, &settings, &fwd, &grads);
    let all = g
        .means
        .iter()
        .flatten()
        .chain(g.log_scales.iter().flatten())
        .chain(g.rotations.iter().flatten())
        .chain(g.colors.iter().flatten())
        .chain(&g.opacity_logits)
        .chain(&g.confidences);
    let mut largest = 0.0f32;
    for v in all {
        assert!(v.is_finite(), "non-finite gradient");
        largest = largest.max(v.abs());
    }
    (fwd.output, largest)
}

fn is_background(o: &RenderOutput) -> bool {
    o.rgb.iter().all(|&v| v == 0.5) && o.alpha.iter().all(|&a| a == 0.0)
}

#[test]
fn depth_near_zero_is_culled_and_very_far_is_drawn() {
    let (near, _) = render_checked(
        &set_of(&[gaussian(Vec3::new(0.0, 0.0, 1e-4), 1e-4)]),
        &cam(),
    );
    assert!(
        is_background(&near),
        "a centre at 1e-4 m is inside the 0.01 m near plane"
    );
    let (far, _) = render_checked(&set_of(&[gaussian(on_pixel(1e5), 500.0)]), &cam());
    let centre = (H / 2 * W + W / 2) as usize;
    assert!(far.alpha[centre] > 0.5);
    assert!((far.depth[centre] - 1e5).abs() / 1e5 < 1e-6);
}

#[test]
fn tiny_and_huge_scales_stay_finite() {
    let (tiny, _) = render_checked(&set_of(&[gaussian(Vec3::new(0.0, 0.0, 5.0), 1e-6)]), &cam());
    // The 0.3 px^2 dilation keeps a point-sized Gaussian visible as a sub-pixel dot.
    let lit = tiny.alpha.iter().filter(|&&a| a > 0.0).count();
    assert!((1..=16).contains(&lit), "{lit} pixels lit");
    let (huge, _) = render_checked(&set_of(&[gaussian(Vec3::new(0.0, 0.0, 5.0), 1e4)]), &cam());
    // Flat over the whole image: every pixel sees opacity * exp(~0).
    assert!(huge.alpha.iter().all(|&a| (a - 0.8).abs() < 1e-4));
}

#[test]
fn zero_and_unnormalised_quaternions_follow_the_rule() {
    let mut g = gaussian(Vec3::new(0.3, -0.2, 4.0), 0.2);
    g.log_scale = Vec3::new(0.3f32.ln(), 0.05f32.ln(), 0.1f32.ln());
    let (identity, _) = render_checked(&set_of(&[g]), &cam());
    g.rotation = Quat::from_xyzw(0.0, 0.0, 0.0, 0.0);
    let (zero, _) = render_checked(&set_of(&[g]), &cam());
    assert_eq!(identity, zero, "a zero quaternion is the identity rotation");
    let q = Quat::from_rotation_z(0.7);
    g.rotation = q;
    let (unit, _) = render_checked(&set_of(&[g]), &cam());
    g.rotation = q * 123.0;
    let (scaled, _) = render_checked(&set_of(&[g]), &cam());
    let max = unit
        .rgb
        .iter()
        .zip(&scaled.rgb)
        .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(max < 1e-5, "a quaternion's norm must not matter: {max}");
    assert_ne!(unit, identity);
}

#[test]
fn opacity_zero_contributes_nothing_and_one_is_clamped() {
    let mut g = gaussian(on_pixel(3.0), 0.5);
    g.opacity = 0.0;
    let (clear, _) = render_checked(&set_of(&[g]), &cam());
    assert!(is_background(&clear));
    g.opacity = 1.0;
    let (opaque, _) = render_checked(&set_of(&[g]), &cam());
    let max_alpha = opaque.alpha.iter().fold(0.0f32, |m, &a| m.max(a));
    assert!(
        (max_alpha - MAX_ALPHA as f32).abs() < 1e-6,
        "one Gaussian leaves 1% through: {max_alpha}"
    );
    // Out-of-range opacities are clamped to [0, 1].
    g.opacity = 7.0;
    assert_eq!(render_checked(&set_of(&[g]), &cam()).0, opaque);
}

#[test]
fn a_saturated_stack_stops_compositing_and_stays_finite() {
    let stack: Vec<Gaussian> = (0..200)
        .map(|i| {
            let mut g = gaussian(Vec3::new(0.0, 0.0, 2.0 + i as f32 * 0.01), 50.0);
            g.opacity = 1.0;
            g
        })
        .collect();
    let (o, _) = render_checked(&set_of(&stack), &cam());
    // 0.99 per layer: compositing stops at the layer that would leave less than 1e-4, the
    // second or third depending on the rounding of 0.01 * 0.01; never later.
    let first = o.alpha[0];
    assert!(o.alpha.iter().all(|&a| a == first));
    assert!((0.99..=0.9999 + 1e-6).contains(&first), "alpha {first}");
    assert!(o.depth.iter().all(|&d| (2.0..2.02).contains(&d)));
}

#[test]
fn non_finite_input_is_skipped_never_propagated() {
    let good = gaussian(Vec3::new(0.0, 0.0, 4.0), 0.3);
    let (clean, _) = render_checked(&set_of(&[good]), &cam());
    let mut bad = Vec::new();
    for k in 0..6 {
        let mut g = gaussian(Vec3::new(0.1, 0.1, 3.0), 0.3);
        let v = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][k % 3];
        match k {
            0 => g.mean.x = v,
            1 => g.log_scale.y = v,
            2 => g.rotation = Quat::from_xyzw(v, 0.0, 0.0, 1.0),
            3 => g.opacity = v,
            4 => g.color.z = v,
            _ => g.confidence = v,
        }
        bad.push(g);
    }
    // A log scale of +inf overflows to an infinite covariance: culled by the same rule.
    bad.push(gaussian(Vec3::new(0.0, 0.0, 3.0), f32::MAX));
    bad.push(good);
    let (mixed, _) = render_checked(&set_of(&bad), &cam());
    assert_eq!(
        mixed, clean,
        "bad Gaussians must be skipped, leaving the good one's image"
    );
}

#[test]
fn a_camera_far_from_the_origin_sees_the_same_image() {
    // Positions on a 1/64 m grid are exact in f32 at 1e5 m, so the only difference between the
    // two renders is the rasterizer's own arithmetic: the camera centre is subtracted first.
    let local: Vec<Gaussian> = (0..40)
        .map(|i| {
            let f = i as f32;
            let mut g = gaussian(
                Vec3::new(
                    (f * 7.0 % 13.0 - 6.0) / 4.0,
                    (f * 5.0 % 9.0 - 4.0) / 8.0,
                    3.0 + f / 8.0,
                ),
                0.15,
            );
            g.color = Vec3::new(f / 40.0, 1.0 - f / 40.0, 0.5);
            g
        })
        .collect();
    let offset = Vec3::new(1.0e5, -1.0e5, 1.0e5);
    let far_set: Vec<Gaussian> = local
        .iter()
        .map(|g| Gaussian {
            mean: g.mean + offset,
            ..*g
        })
        .collect();
    let k = Intrinsics::from_hfov(W, H, 90.0);
    let rot = Quat::from_rotation_y(0.05);
    let cam_here = Camera::from_camera_to_world(k, rot, Vec3::ZERO);
    let cam_far = Camera::from_camera_to_world(k, rot, offset);
    let (here, _) = render_checked(&set_of(&local), &cam_here);
    let (far, _) = render_checked(&set_of(&far_set), &cam_far);
    let max = here
        .rgb
        .iter()
        .zip(&far.rgb)
        .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(max < 1e-5, "max rgb difference {max}");
    assert!(here.alpha.iter().any(|&a| a > 0.5));
}

#[test]
fn an_empty_set_renders_the_background() {
    let (o, g) = render_checked(&GaussianSet::default(), &cam());
    assert!(is_background(&o));
    assert_eq!(g, 0.0);
    assert!(o.depth.iter().all(|&d| d == 0.0));
}
