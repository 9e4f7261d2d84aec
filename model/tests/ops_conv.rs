//! `ops::Conv` against candle's own convolution: the same outputs, and (on the gradient
//! path, taken when the weights are variables) the same input and weight gradients as
//! candle's convolution backward, for the kernel sizes, strides and paddings the network and
//! LPIPS use. Sizes are chosen so that the strides tile the padded input exactly: candle's
//! own backward (the reference) fails on the other sizes.

use candle_core::{DType, Device, Module, Tensor, Var};
use candle_nn::{VarBuilder, VarMap};
use model::ops::Conv;

fn max_diff(a: &Tensor, b: &Tensor) -> f64 {
    (a - b)
        .unwrap()
        .to_dtype(DType::F64)
        .unwrap()
        .abs()
        .unwrap()
        .flatten_all()
        .unwrap()
        .max(0)
        .unwrap()
        .to_scalar::<f64>()
        .unwrap()
}

#[test]
fn gemm_convolution_matches_candle_in_value_and_gradient() {
    let dev = Device::Cpu;
    // (in, out, kernel, stride, padding, bias, height, width)
    let cases = [
        (3, 4, 3, 1, 1, true, 9, 13),
        (4, 5, 3, 2, 1, true, 11, 15),
        (3, 6, 11, 4, 2, true, 39, 43),
        (6, 2, 1, 1, 0, false, 5, 7),
        (2, 3, 5, 1, 2, true, 8, 8),
    ];
    for (cin, cout, k, s, p, bias, h, w) in cases {
        let varmap = VarMap::new();
        let vb = VarBuilder::from_varmap(&varmap, DType::F64, &dev);
        let conv = Conv::new(vb, (cin, cout), k, s, p, bias).unwrap();
        let x = Var::from_tensor(&Tensor::randn(0f64, 1.0, (2, cin, h, w), &dev).unwrap()).unwrap();
        let vars = varmap.all_vars();
        let weight = vars.iter().find(|v| v.rank() == 4).unwrap();

        let ours = conv.forward(x.as_tensor()).unwrap();
        let mut reference = x
            .as_tensor()
            .conv2d(weight.as_tensor(), p, s, 1, 1)
            .unwrap();
        if let Some(b) = vars.iter().find(|v| v.rank() == 1) {
            reference = reference
                .broadcast_add(&b.as_tensor().reshape((1, cout, 1, 1)).unwrap())
                .unwrap();
        }
        assert_eq!(ours.dims(), reference.dims());
        assert!(max_diff(&ours, &reference) < 1e-10, "value k{k} s{s}");

        // Weigh the outputs so every output pixel has a distinct gradient.
        let weights = Tensor::randn(0f64, 1.0, ours.dims(), &dev).unwrap();
        let g_ours = (&ours * &weights)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        let g_ref = (&reference * &weights)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        for v in [&x, weight] {
            let (a, b) = (
                g_ours.get(v.as_tensor()).unwrap(),
                g_ref.get(v.as_tensor()).unwrap(),
            );
            assert!(
                max_diff(a, b) < 1e-9,
                "gradient k{k} s{s}: {}",
                max_diff(a, b)
            );
        }
    }
}

#[test]
fn inference_path_equals_the_gradient_path() {
    let dev = Device::Cpu;
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &dev);
    let conv = Conv::new(vb, (3, 8), 3, 2, 1, true).unwrap();
    let x = Tensor::randn(0f32, 1.0, (1, 3, 12, 20), &dev).unwrap();
    let tracked = conv.forward(&x).unwrap();
    // The same weights as plain tensors: no gradient is tracked, candle's kernel runs.
    let plain: std::collections::HashMap<String, Tensor> = varmap
        .data()
        .lock()
        .unwrap()
        .iter()
        .map(|(k, v)| (k.clone(), v.as_tensor().detach()))
        .collect();
    let vb = VarBuilder::from_tensors(plain, DType::F32, &dev);
    let fixed = Conv::new(vb, (3, 8), 3, 2, 1, true).unwrap();
    let untracked = fixed.forward(&x).unwrap();
    assert!(max_diff(&tracked, &untracked) < 1e-5);
}
