//! The CPU backward pass against central finite differences, both in f64.
//!
//! Loss: a fixed random weighting of every output image (rgb, normalised and raw depth,
//! alpha, confidence), so every path of the backward pass is exercised at once. Each raw
//! parameter of each Gaussian is perturbed by +-1e-6 and the forward pass re-run.
//! Tolerance: |analytic - numeric| <= 1e-6 + 1e-5 * max(|analytic|, |numeric|) for every
//! parameter. The rasterizer has discontinuities (tile-rectangle edges, the 1/255 skip, the
//! 0.99 clamp, early termination); at a step of 1e-6 none of the fixed seeds below sits on
//! one, and a seed that did would fail loudly rather than be skipped.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::cpu::{backward, render, OutputGrads, SplatGrads};
use renderer::gaussians::SplatsOwned;
use renderer::{scene, Camera, CameraParams, Intrinsics, RenderSettings};

struct Loss {
    rgb: Vec<f64>,
    depth: Vec<f64>,
    depth_raw: Vec<f64>,
    alpha: Vec<f64>,
    confidence: Vec<f64>,
}

impl Loss {
    fn random(seed: u64, pixels: usize) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut v = |n: usize, s: f64| {
            (0..n)
                .map(|_| rng.random_range(-s..s))
                .collect::<Vec<f64>>()
        };
        Self {
            rgb: v(3 * pixels, 1.0),
            depth: v(pixels, 0.1),
            depth_raw: v(pixels, 0.1),
            alpha: v(pixels, 1.0),
            confidence: v(pixels, 1.0),
        }
    }

    fn value(
        &self,
        s: &SplatsOwned<f64>,
        cam: &CameraParams<f64>,
        settings: &RenderSettings,
    ) -> f64 {
        let o = render(&s.view(), cam, settings).output;
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        dot(&o.rgb, &self.rgb)
            + dot(&o.depth, &self.depth)
            + dot(&o.depth_raw, &self.depth_raw)
            + dot(&o.alpha, &self.alpha)
            + dot(&o.confidence, &self.confidence)
    }

    fn grads(&self) -> OutputGrads<'_, f64> {
        OutputGrads {
            rgb: Some(&self.rgb),
            depth: Some(&self.depth),
            depth_raw: Some(&self.depth_raw),
            alpha: Some(&self.alpha),
            confidence: Some(&self.confidence),
        }
    }
}

fn logit(p: f64) -> f64 {
    (p / (1.0 - p)).ln()
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// Checks every raw parameter of every Gaussian of a seeded scene (after `edit`); returns
/// how many were checked and the worst relative error.
fn check_scene(
    seed: u64,
    n: usize,
    background: [f32; 3],
    edit: impl Fn(&mut renderer::GaussianSet),
) -> (usize, f64) {
    let k = Intrinsics::from_hfov(40, 36, 70.0);
    let mut set = scene::small_overlapping(seed, n, &k);
    edit(&mut set);
    let base = SplatsOwned::<f64>::from_set(&set);
    let cam: CameraParams<f64> = Camera::identity(k).params();
    let settings = RenderSettings {
        background,
        ..Default::default()
    };
    let loss = Loss::random(seed + 100, (k.width * k.height) as usize);
    let fwd = render(&base.view(), &cam, &settings);
    assert!(
        fwd.output.alpha.iter().any(|&a| a > 0.5),
        "scene must be visible"
    );
    let g: SplatGrads<f64> = backward(&base.view(), &cam, &settings, &fwd, &loss.grads());

    let h = 1e-6;
    let mut checked = 0;
    let mut worst: f64 = 0.0;
    let mut compare = |what: String,
                       analytic: f64,
                       perturb: &dyn Fn(&mut SplatsOwned<f64>, f64)| {
        let (mut plus, mut minus) = (base.clone(), base.clone());
        perturb(&mut plus, h);
        perturb(&mut minus, -h);
        let numeric =
            (loss.value(&plus, &cam, &settings) - loss.value(&minus, &cam, &settings)) / (2.0 * h);
        let err = (analytic - numeric).abs();
        let tol = 1e-6 + 1e-5 * analytic.abs().max(numeric.abs());
        assert!(
            err <= tol,
            "seed {seed} {what}: analytic {analytic:.9e} numeric {numeric:.9e}"
        );
        worst = worst.max(err / (1e-6 + analytic.abs().max(numeric.abs())));
        checked += 1;
    };
    for i in 0..n {
        for d in 0..3 {
            compare(format!("mean[{i}][{d}]"), g.means[i][d], &|s, e| {
                s.means[i][d] += e
            });
            compare(
                format!("log_scale[{i}][{d}]"),
                g.log_scales[i][d],
                &|s, e| s.log_scales[i][d] += e,
            );
            compare(format!("color[{i}][{d}]"), g.colors[i][d], &|s, e| {
                s.colors[i][d] += e
            });
        }
        // Quaternions are perturbed off the unit sphere: the gradient is for the raw input.
        for d in 0..4 {
            compare(format!("rotation[{i}][{d}]"), g.rotations[i][d], &|s, e| {
                s.rotations[i][d] += e
            });
        }
        compare(
            format!("opacity_logit[{i}]"),
            g.opacity_logits[i],
            &|s, e| s.opacities[i] = sigmoid(logit(s.opacities[i]) + e),
        );
        compare(format!("confidence[{i}]"), g.confidences[i], &|s, e| {
            s.confidences[i] += e
        });
    }
    (checked, worst)
}

#[test]
fn gradients_match_finite_differences_on_random_small_scenes() {
    let mut total = 0;
    for seed in [1, 2, 3] {
        let (checked, worst) = check_scene(seed, 10, [0.2, 0.5, 0.9], |_| {});
        eprintln!("seed {seed}: {checked} parameters, worst relative error {worst:.2e}");
        total += checked;
    }
    assert_eq!(total, 3 * 10 * 15);
}

#[test]
fn gradients_hold_where_the_frustum_clamp_applies() {
    // Large Gaussians centred beyond 1.3x the half field of view (left, right, below) whose
    // footprints still reach into the image: the Jacobian uses the clamped direction there.
    let (checked, _) = check_scene(11, 6, [0.0; 3], |set| {
        for (i, m) in set.means.iter_mut().enumerate() {
            let side = [-1.0, 1.0, 0.0][i % 3];
            let down = if i % 3 == 2 { 1.0 } else { 0.0 };
            m.x = side * 1.2 * m.z;
            m.y = down * 1.2 * m.z;
            set.log_scales[i] = glam::Vec3::splat((0.45 * m.z).ln());
        }
    });
    assert_eq!(checked, 6 * 15);
}

#[test]
fn gradients_hold_for_non_unit_quaternions() {
    let k = Intrinsics::from_hfov(32, 32, 60.0);
    let mut set = scene::small_overlapping(9, 4, &k);
    for q in set.rotations.iter_mut() {
        *q *= 3.7; // far from unit norm: normalisation is part of the differentiated function
    }
    let base = SplatsOwned::<f64>::from_set(&set);
    let cam: CameraParams<f64> = Camera::identity(k).params();
    let settings = RenderSettings::default();
    let loss = Loss::random(5, 32 * 32);
    let fwd = render(&base.view(), &cam, &settings);
    let g = backward(&base.view(), &cam, &settings, &fwd, &loss.grads());
    for i in 0..4 {
        // Scaling a quaternion leaves the image unchanged, so the gradient is orthogonal to it.
        let dot: f64 = (0..4)
            .map(|d| g.rotations[i][d] * base.rotations[i][d])
            .sum();
        assert!(dot.abs() < 1e-9, "gradient not tangent: {dot}");
        for d in 0..4 {
            let (mut p, mut m) = (base.clone(), base.clone());
            p.rotations[i][d] += 1e-6;
            m.rotations[i][d] -= 1e-6;
            let numeric =
                (loss.value(&p, &cam, &settings) - loss.value(&m, &cam, &settings)) / 2e-6;
            assert!((numeric - g.rotations[i][d]).abs() <= 1e-6 + 1e-5 * numeric.abs());
        }
    }
}

#[test]
fn f32_gradients_agree_with_f64() {
    let k = Intrinsics::from_hfov(40, 36, 70.0);
    let set = scene::small_overlapping(4, 10, &k);
    let settings = RenderSettings::default();
    let loss = Loss::random(4, 40 * 36);
    let cam64: CameraParams<f64> = Camera::identity(k).params();
    let s64 = SplatsOwned::<f64>::from_set(&set);
    let g64 = backward(
        &s64.view(),
        &cam64,
        &settings,
        &render(&s64.view(), &cam64, &settings),
        &loss.grads(),
    );

    let cam32: CameraParams<f32> = Camera::identity(k).params();
    let v32 = set.view().unwrap();
    let l32 = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    let (rgb, depth, depth_raw, alpha, conf) = (
        l32(&loss.rgb),
        l32(&loss.depth),
        l32(&loss.depth_raw),
        l32(&loss.alpha),
        l32(&loss.confidence),
    );
    let grads = OutputGrads {
        rgb: Some(&rgb),
        depth: Some(&depth),
        depth_raw: Some(&depth_raw),
        alpha: Some(&alpha),
        confidence: Some(&conf),
    };
    let g32 = backward(
        &v32,
        &cam32,
        &settings,
        &render(&v32, &cam32, &settings),
        &grads,
    );
    let scale = g64
        .means
        .iter()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in g32.means.iter().flatten().zip(g64.means.iter().flatten()) {
        assert!((*a as f64 - b).abs() <= 1e-3 * scale, "f32 {a} vs f64 {b}");
    }
}
