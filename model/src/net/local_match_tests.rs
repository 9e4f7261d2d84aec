use super::*;
use crate::net::geometry::test_camera;
use candle_core::{DType, Device, IndexOp, Var};
use candle_nn::VarMap;

/// `tiny` with the stage on: `samples` depths over ±`span` candidate spacings.
fn config(samples: usize, span: f32) -> Config {
    Config::tiny()
        .with_settings(&[
            format!("local_match.samples={samples}"),
            format!("local_match.span={span}"),
        ])
        .unwrap()
}

/// The stage with fresh variables (its output convolution at zero, as built).
fn stage(cfg: &Config) -> (LocalMatch, VarMap) {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    (LocalMatch::new(vb, cfg).unwrap(), varmap)
}

/// Normalised inverse depth of `depth` metres in `cfg`'s candidate range.
fn normalised(depth: f64, cfg: &Config) -> f32 {
    let (a, b) = (1.0 / cfg.near as f64, 1.0 / cfg.far as f64);
    ((1.0 / depth - b) / (a - b)) as f32
}

fn finite(t: &Tensor) -> bool {
    t.flatten_all()
        .unwrap()
        .to_vec1::<f32>()
        .unwrap()
        .iter()
        .all(|v| v.is_finite())
}

#[test]
fn offsets_spread_evenly_over_the_span() {
    let lm = LocalMatchConfig {
        samples: 5,
        span: 2.0,
        channels: 4,
    };
    let got = lm.offsets(33);
    let want = [-2.0, -1.0, 0.0, 1.0, 2.0].map(|k: f64| k / 32.0);
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() < 1e-12, "{got:?}");
    }
    assert!(!LocalMatchConfig::default().enabled());
}

#[test]
fn an_even_sample_count_or_no_span_is_refused() {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    assert!(LocalMatch::new(vb.clone(), &config(4, 3.0)).is_err());
    assert!(LocalMatch::new(vb.clone(), &config(5, 0.0)).is_err());
    assert!(LocalMatch::new(vb, &Config::tiny()).is_err());
}

#[test]
fn correlation_peaks_at_the_true_depth_of_a_rectified_pair() {
    let cfg = config(5, 2.0);
    let (lm, _vars) = stage(&cfg);
    let (c, h, w) = (16, 20, 40);
    let left = Tensor::randn(0f32, 1.0, (1, c, h, w), &Device::Cpu).unwrap();
    // 2 half-resolution pixels of disparity, 4 image pixels: 100 x 0.5 / 4 = 12.5 m.
    let right = left
        .narrow(3, 2, w - 2)
        .unwrap()
        .pad_with_zeros(3, 0, 2)
        .unwrap();
    let features = Tensor::cat(&[&left, &right], 0).unwrap();
    // The estimate one sampling step (one candidate spacing) too far: the truth is sample 3.
    let step = 1.0 / (cfg.candidates - 1) as f32;
    let coarse = Tensor::full(normalised(12.5, &cfg) - step, (2, 1, h, w), &Device::Cpu).unwrap();
    let cameras = [test_camera(0.0), test_camera(0.5)];
    let profile = lm
        .correlation(&LocalInputs {
            coarse: &coarse,
            features: &features,
            cameras: &cameras,
            stride: 2,
        })
        .unwrap();
    assert_eq!(profile.dims(), &[2, 5, h, w]);
    // Left view, pixels whose matches at every sampled depth lie inside the right view.
    let best: Vec<u32> = profile
        .i((0, .., .., 4..w))
        .unwrap()
        .argmax(0)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    assert!(best.iter().all(|&b| b == 3), "{best:?}");
    let peak: Vec<f32> = profile
        .i((0, 3, .., 4..w))
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    assert!(peak.iter().all(|&p| (p - 1.0).abs() < 1e-3), "{peak:?}");
}

#[test]
fn the_untrained_stage_returns_the_coarse_estimate() {
    let cfg = config(9, 3.0);
    let (lm, _vars) = stage(&cfg);
    let features = Tensor::randn(0f32, 1.0, (2, 16, 10, 20), &Device::Cpu).unwrap();
    let coarse = Tensor::rand(0f32, 1.0, (2, 1, 10, 20), &Device::Cpu).unwrap();
    let out = lm
        .forward(&LocalInputs {
            coarse: &coarse,
            features: &features,
            cameras: &[test_camera(0.0), test_camera(0.3)],
            stride: 2,
        })
        .unwrap();
    let diff = (out - &coarse).unwrap().abs().unwrap().max_all().unwrap();
    assert_eq!(diff.to_scalar::<f32>().unwrap(), 0.0);
}

#[test]
fn extremes_stay_finite_with_finite_gradients() {
    let cfg = config(9, 3.0);
    let (lm, varmap) = stage(&cfg);
    // Give the output convolution weight so gradients reach every variable.
    for (name, var) in varmap.data().lock().unwrap().iter() {
        if name.contains("zero_out") {
            var.set(&(var.ones_like().unwrap() * 0.1).unwrap()).unwrap();
        }
    }
    let (h, w) = (10, 20);
    let far_away = |x: f32| {
        let c = test_camera(x);
        Camera::from_camera_to_world(
            c.intrinsics,
            glam::Quat::IDENTITY,
            glam::Vec3::new(1.0e5 + x, -3.0e4, 2.0e5),
        )
    };
    let backwards = Camera::from_camera_to_world(
        test_camera(0.0).intrinsics,
        glam::Quat::from_rotation_y(std::f32::consts::PI),
        glam::Vec3::new(0.2, 0.0, 0.0),
    );
    let feature_sets = [
        (
            "random",
            Tensor::randn(0f32, 1.0, (2, 16, h, w), &Device::Cpu).unwrap(),
        ),
        (
            "empty",
            Tensor::zeros((2, 16, h, w), DType::F32, &Device::Cpu).unwrap(),
        ),
        (
            "saturated",
            Tensor::full(1e4f32, (2, 16, h, w), &Device::Cpu).unwrap(),
        ),
    ];
    let rigs = [
        ("near origin", vec![test_camera(0.0), test_camera(0.5)]),
        ("far from the origin", vec![far_away(0.0), far_away(0.5)]),
        ("partner facing away", vec![test_camera(0.0), backwards]),
    ];
    // Depth at the near candidate (1 m), the far one (100 m), and beyond both (clamped).
    for level in [0f32, 1.0, -0.5, 1.5] {
        for (what, features) in &feature_sets {
            for (rig, cameras) in &rigs {
                let features = Var::from_tensor(features).unwrap();
                let coarse =
                    Var::from_tensor(&Tensor::full(level, (2, 1, h, w), &Device::Cpu).unwrap())
                        .unwrap();
                let out = lm
                    .forward(&LocalInputs {
                        coarse: coarse.as_tensor(),
                        features: features.as_tensor(),
                        cameras,
                        stride: 2,
                    })
                    .unwrap();
                let case = format!("{what} features, {rig}, level {level}");
                assert!(finite(&out), "{case}");
                let v: Vec<f32> = out.flatten_all().unwrap().to_vec1().unwrap();
                assert!(v.iter().all(|x| (0.0..=1.0).contains(x)), "{case}");
                let grads = out.sqr().unwrap().sum_all().unwrap().backward().unwrap();
                assert!(finite(grads.get(&features).unwrap()), "{case}: features");
                for (name, var) in varmap.data().lock().unwrap().iter() {
                    if let Some(g) = grads.get(var) {
                        assert!(finite(g), "{case}: {name}");
                    }
                }
            }
        }
    }
}

#[test]
fn a_single_view_has_a_flat_profile() {
    let cfg = config(5, 2.0);
    let (lm, _vars) = stage(&cfg);
    let features = Tensor::randn(0f32, 1.0, (1, 16, 10, 20), &Device::Cpu).unwrap();
    let coarse = Tensor::full(0.5f32, (1, 1, 10, 20), &Device::Cpu).unwrap();
    let profile = lm
        .correlation(&LocalInputs {
            coarse: &coarse,
            features: &features,
            cameras: &[test_camera(0.0)],
            stride: 2,
        })
        .unwrap();
    let max = profile
        .abs()
        .unwrap()
        .max_all()
        .unwrap()
        .to_scalar::<f32>()
        .unwrap();
    assert_eq!(max, 0.0);
}
