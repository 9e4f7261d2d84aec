//! The StereoSplat network (untrained weights): shapes for 1 to 3 pairs, pruning to the
//! opacity floor and budget, and numerical stability at the extremes of its input:
//! uniform grey, black and saturated images, identical left and right images (zero
//! disparity), a scene at 1 m and at 80 m, cameras far from the origin, with the census
//! correlation on, and a narrowed depth range (`auto_depth_range`). Every output and
//! every gradient (through the differentiable rasterizer) must be finite.

use crate::finite_support;
use crate::var_support;

use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use finite_support::{assert_finite, assert_finite_gradients};
use glam::{Quat, Vec3};
use model::net::depth_range::DepthRange;
use model::net::{to_set, Config, StereoSplat};
use model::ops::render;
use renderer::{Camera, Intrinsics, RenderSettings};

const W: u32 = 96;
const H: u32 = 40;
const BASELINE: f32 = 0.6;

fn intrinsics() -> Intrinsics {
    Intrinsics::from_hfov(W, H, 80.0)
}

/// A rectified pair at `origin` (left camera), looking down +z, and the frame `ahead` metres on.
fn pair(origin: Vec3, ahead: f32) -> Vec<Camera> {
    [0.0, BASELINE]
        .iter()
        .map(|&x| {
            Camera::from_camera_to_world(
                intrinsics(),
                Quat::IDENTITY,
                origin + Vec3::new(x, 0.0, ahead),
            )
        })
        .collect()
}

fn network() -> (VarMap, StereoSplat) {
    network_of(&Config::tiny())
}

fn network_of(cfg: &Config) -> (VarMap, StereoSplat) {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    let net = StereoSplat::new(vb, cfg).unwrap();
    (varmap, net)
}

/// A textured image: stripes whose phase is shifted by `shift` pixels.
fn stripes(shift: f32) -> Vec<f32> {
    let mut v = Vec::with_capacity((3 * W * H) as usize);
    for c in 0..3 {
        for y in 0..H {
            for x in 0..W {
                let t = (x as f32 + shift) * 0.7 + y as f32 * 0.3 + c as f32;
                v.push(0.5 + 0.4 * t.sin());
            }
        }
    }
    v
}

fn images(views: &[Vec<f32>]) -> Tensor {
    let data: Vec<f32> = views.iter().flatten().copied().collect();
    Tensor::from_vec(data, (views.len(), 3, H as usize, W as usize), &Device::Cpu).unwrap()
}

/// Forward, render a target view, backward: every output and gradient finite.
fn check_stable(views: &[Vec<f32>], cameras: &[Camera], what: &str) {
    check_stable_with(&Config::tiny(), views, cameras, what);
}

/// [`check_stable`] for the network of `cfg`.
fn check_stable_with(cfg: &Config, views: &[Vec<f32>], cameras: &[Camera], what: &str) {
    let (varmap, net) = network_of(cfg);
    let p = net.forward(&images(views), cameras).unwrap();
    let s = &p.splats;
    for (t, name) in [
        (&s.means, "means"),
        (&s.log_scales, "log_scales"),
        (&s.rotations, "rotations"),
        (&s.opacity_logits, "opacity"),
        (&s.colors, "colors"),
        (&s.confidences, "confidences"),
        (&p.depth, "depth"),
    ] {
        assert_finite(t, &format!("{what}: {name}"));
    }
    let target = Camera {
        position: cameras[0].position + Vec3::new(0.0, 0.0, 2.0),
        ..cameras[0]
    };
    let out = render(&s.pack().unwrap(), &target, &RenderSettings::default()).unwrap();
    assert_finite(&out, &format!("{what}: render"));
    let loss = (out.sqr().unwrap().mean_all().unwrap() + p.depth.mean_all().unwrap()).unwrap();
    let grads = loss.backward().unwrap();
    let with_grad = assert_finite_gradients(&varmap, &grads, what);
    assert!(
        with_grad > 10,
        "{what}: only {with_grad} variables got a gradient"
    );
}

#[test]
fn gaussians_per_view_and_pair_counts() {
    let (_, net) = network();
    for pairs in 1..=3 {
        let mut cams = Vec::new();
        let mut views = Vec::new();
        for k in 0..pairs {
            cams.extend(pair(Vec3::ZERO, 1.5 * k as f32));
            views.push(stripes(0.0));
            views.push(stripes(3.0));
        }
        let p = net.forward(&images(&views), &cams).unwrap();
        // One Gaussian per 2x2 pixels of every view.
        let per_view = (W as usize / 2) * (H as usize / 2);
        assert_eq!(p.splats.means.dims(), &[2 * pairs * per_view, 3]);
        assert_eq!(
            p.depth.dims(),
            &[2 * pairs, 1, H as usize / 2, W as usize / 2]
        );
        let cfg = Config::tiny();
        let d: Vec<f32> = p.depth.flatten_all().unwrap().to_vec1().unwrap();
        assert!(d
            .iter()
            .all(|&z| z >= cfg.near * 0.999 && z <= cfg.far * 1.001));
    }
}

#[test]
fn pruning_keeps_the_floor_and_the_budget() {
    let (_, net) = network();
    let p = net
        .forward(
            &images(&[stripes(0.0), stripes(3.0)]),
            &pair(Vec3::ZERO, 0.0),
        )
        .unwrap();
    let all = to_set(&p.splats, None, 0.0, usize::MAX).unwrap();
    assert_eq!(all.len(), p.splats.means.dim(0).unwrap());
    // The weights are untrained and unseeded (candle's CPU generator takes no seed), so the
    // floor is the median opacity: half the splats are above it on every draw.
    let mut opacities = all.opacities.clone();
    opacities.sort_by(|a, b| a.total_cmp(b));
    let floor = opacities[opacities.len() / 2];
    let above = to_set(&p.splats, None, floor, usize::MAX).unwrap();
    assert!(above.opacities.iter().all(|&o| o >= floor));
    assert!(
        above.len() >= all.len() / 2,
        "{} of {}",
        above.len(),
        all.len()
    );
    let budget = above.len() / 3;
    assert!(budget > 0);
    let capped = to_set(&p.splats, None, floor, budget).unwrap();
    assert_eq!(capped.len(), budget);
    // The budget keeps the most opaque.
    let least_kept = capped.opacities.iter().copied().fold(1.0, f32::min);
    let mut sorted = above.opacities.clone();
    sorted.sort_by(|a, b| b.total_cmp(a));
    assert!(least_kept >= sorted[budget]);
}

#[test]
fn uniform_grey_black_and_saturated_images_stay_finite() {
    let n = (3 * W * H) as usize;
    for (value, what) in [(0.5, "grey"), (0.0, "black"), (1.0, "saturated")] {
        let v = vec![value; n];
        check_stable(&[v.clone(), v], &pair(Vec3::ZERO, 0.0), what);
    }
}

#[test]
fn unbounded_depth_logits_stay_finite_at_the_extremes() {
    let cfg = Config::tiny()
        .with_settings(&["depth_logit_bound=null"])
        .unwrap();
    let n = (3 * W * H) as usize;
    let fx = intrinsics().fx;
    check_stable_with(
        &cfg,
        &[vec![0.0; n], vec![0.0; n]],
        &pair(Vec3::ZERO, 0.0),
        "black",
    );
    let v = stripes(0.0);
    check_stable_with(
        &cfg,
        &[v.clone(), v],
        &pair(Vec3::ZERO, 0.0),
        "zero disparity",
    );
    let far = stripes(fx * BASELINE / 80.0);
    check_stable_with(&cfg, &[stripes(0.0), far], &pair(Vec3::ZERO, 0.0), "80 m");
}

#[test]
fn census_matching_stays_finite_at_the_extremes() {
    check_extremes(
        &Config::tiny()
            .with_settings(&["census_matching=true"])
            .unwrap(),
    );
}

/// Black and saturated pairs, a 1 m scene posed far from the origin: finite outputs and
/// gradients for the network of `cfg`.
fn check_extremes(cfg: &Config) {
    let n = (3 * W * H) as usize;
    for (value, what) in [(0.0, "black"), (1.0, "saturated")] {
        let v = vec![value; n];
        check_stable_with(cfg, &[v.clone(), v], &pair(Vec3::ZERO, 0.0), what);
    }
    let far = Vec3::new(1.0e5, -1.0e5, 50.0);
    let shifted = stripes(intrinsics().fx * BASELINE / 1.0);
    check_stable_with(
        cfg,
        &[stripes(0.0), shifted],
        &pair(far, 0.0),
        "1 m, far pose",
    );
}

#[test]
fn a_narrowed_depth_range_bounds_the_depth_and_passes_gradients() {
    let (varmap, net) = network();
    for (near, far) in [(2.0f32, 8.0f32), (1.0, 3.0), (33.0, 100.0)] {
        let ranged = net.with_depth_range(DepthRange { near, far });
        let cameras = pair(Vec3::ZERO, 0.0);
        let p = ranged
            .forward(&images(&[stripes(0.0), stripes(4.0)]), &cameras)
            .unwrap();
        let depth: Vec<f32> = p.depth.flatten_all().unwrap().to_vec1().unwrap();
        assert!(
            depth
                .iter()
                .all(|d| (near * 0.999..=far * 1.001).contains(d)),
            "{near}..{far}: {:?}",
            depth
                .iter()
                .copied()
                .fold((f32::MAX, f32::MIN), |(a, b), d| (a.min(d), b.max(d)))
        );
        let grads = p.depth.mean_all().unwrap().backward().unwrap();
        let what = format!("{near}..{far}");
        assert!(
            assert_finite_gradients(&varmap, &grads, &what) > 10,
            "{what}"
        );
    }
}

#[test]
fn identical_left_and_right_images_stay_finite() {
    let v = stripes(0.0);
    check_stable(&[v.clone(), v], &pair(Vec3::ZERO, 0.0), "zero disparity");
}

#[test]
fn scenes_at_1_m_and_80_m_stay_finite() {
    let fx = intrinsics().fx;
    for depth in [1.0f32, 80.0] {
        let disparity = fx * BASELINE / depth;
        check_stable(
            &[stripes(0.0), stripes(disparity)],
            &pair(Vec3::ZERO, 0.0),
            &format!("{depth} m"),
        );
    }
}

#[test]
fn cameras_far_from_the_origin_stay_finite() {
    let far = Vec3::new(1.0e5, -1.0e5, 50.0);
    check_stable(&[stripes(0.0), stripes(3.0)], &pair(far, 0.0), "far pose");
}

#[test]
fn missing_weights_and_unknown_presets_are_typed_errors() {
    use model::methods::{build, MethodError};
    use model::net::LoadError;
    let missing = build(
        "stereosplat",
        Some("tiny"),
        Some(std::path::Path::new("/nonexistent/weights.safetensors")),
        &[],
    );
    assert!(matches!(
        missing,
        Err(MethodError::Weights(LoadError::Missing(_)))
    ));
    assert!(matches!(
        build("stereosplat", Some("huge"), None, &[]),
        Err(MethodError::Preset(_))
    ));
    let setting = |s: &str| build("stereosplat", None, None, &[s.to_string()]);
    assert!(matches!(
        setting("candidates=lots"),
        Err(MethodError::Setting(_))
    ));
    assert!(setting("pair_fusion_margin=0.5").is_ok());
    assert!(matches!(
        build("sgm", None, None, &["candidates=8".to_string()]),
        Err(MethodError::Setting(_))
    ));
    // A file that is not safetensors.
    let junk = std::env::temp_dir().join(format!("stereosplat-junk-{}", std::process::id()));
    std::fs::write(&junk, b"not a weight file").unwrap();
    assert!(matches!(
        build("stereosplat", None, Some(&junk), &[]),
        Err(MethodError::Weights(LoadError::Mismatch { .. }))
    ));
    let _ = std::fs::remove_file(junk);
}

#[test]
fn inference_kernels_compute_what_training_does() {
    // Weights as variables: every layer takes the differentiable path. The same weights as
    // plain tensors: convolution takes the inference im2col, layer norm and attention
    // softmax candle's fused kernels.
    let (varmap, trained) = network();
    let plain = var_support::frozen(&varmap);
    let vb = VarBuilder::from_tensors(plain, DType::F32, &Device::Cpu);
    let inference = StereoSplat::new(vb, &Config::tiny()).unwrap();
    let mut cams = pair(Vec3::ZERO, 0.0);
    cams.extend(pair(Vec3::ZERO, 1.5));
    let views = [stripes(0.0), stripes(3.0), stripes(1.0), stripes(4.0)];
    let a = trained.forward(&images(&views), &cams).unwrap();
    let b = inference.forward(&images(&views), &cams).unwrap();
    for (x, y) in [
        (&a.splats.means, &b.splats.means),
        (&a.splats.colors, &b.splats.colors),
        (&a.splats.opacity_logits, &b.splats.opacity_logits),
        (&a.depth, &b.depth),
    ] {
        let max = |t: &Tensor| -> f32 {
            t.abs()
                .unwrap()
                .flatten_all()
                .unwrap()
                .max(0)
                .unwrap()
                .to_scalar()
                .unwrap()
        };
        // Relative to the values' scale (means and depths reach 100 m): the kernels sum in
        // other orders, seen up to 4e-5; a wrong kernel is off by far more.
        let diff = max(&(x - y).unwrap()) / max(x).max(1.0);
        assert!(diff < 3e-4, "{diff}");
    }
}
