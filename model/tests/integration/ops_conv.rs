//! `ops::Conv` against candle's own convolution: the same outputs, and (on the gradient
//! path, taken when the weights are variables) the same input and weight gradients as
//! candle's convolution backward, for the kernel sizes, strides and paddings the network and
//! LPIPS use. Sizes are chosen so that the strides tile the padded input exactly: candle's
//! own backward (the reference) fails on the other sizes. The inference path (no gradient
//! tracked: `ops::im2col` and one product) is checked on those sizes too.

use crate::var_support;

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

/// The convolution of `x` by candle's own kernel, bias added.
fn candle_conv(x: &Tensor, weight: &Tensor, bias: Option<&Tensor>, s: usize, p: usize) -> Tensor {
    let y = x.conv2d(weight, p, s, 1, 1).unwrap();
    match bias {
        Some(b) => y
            .broadcast_add(&b.reshape((1, b.dim(0).unwrap(), 1, 1)).unwrap())
            .unwrap(),
        None => y,
    }
}

#[test]
fn inference_path_matches_candle_and_the_gradient_path() {
    let dev = Device::Cpu;
    // (in, out, kernel, stride, padding, bias, height, width): the network's shapes, sizes
    // the stride does not tile, a 1x1, no bias.
    let cases = [
        (3, 8, 3, 2, 1, true, 12, 20),
        (3, 8, 3, 2, 1, true, 13, 21),
        (5, 4, 3, 1, 1, false, 7, 9),
        (6, 2, 1, 1, 0, true, 5, 7),
        (3, 6, 11, 4, 2, true, 40, 41),
    ];
    for (cin, cout, k, s, p, bias, h, w) in cases {
        let varmap = VarMap::new();
        let vb = VarBuilder::from_varmap(&varmap, DType::F64, &dev);
        let conv = Conv::new(vb, (cin, cout), k, s, p, bias).unwrap();
        let x = Tensor::randn(0f64, 1.0, (2, cin, h, w), &dev).unwrap();
        let tracked = conv.forward(&x).unwrap();
        // The same weights as plain tensors: no gradient is tracked, the inference path runs.
        let plain = var_support::frozen(&varmap);
        let weight = plain.values().find(|t| t.rank() == 4).unwrap().clone();
        let b = plain.values().find(|t| t.rank() == 1).cloned();
        let vb = VarBuilder::from_tensors(plain, DType::F64, &dev);
        let fixed = Conv::new(vb, (cin, cout), k, s, p, bias).unwrap();
        let untracked = fixed.forward(&x).unwrap();
        let reference = candle_conv(&x, &weight, b.as_ref(), s, p);
        assert_eq!(untracked.dims(), reference.dims(), "k{k} s{s} {h}x{w}");
        assert!(
            max_diff(&untracked, &reference) < 1e-10,
            "k{k} s{s} {h}x{w}"
        );
        assert!(max_diff(&tracked, &untracked) < 1e-10, "k{k} s{s} {h}x{w}");
    }
}

#[test]
fn im2col_unrolls_patches_and_refuses_inputs_smaller_than_the_kernel() {
    use model::ops::{im2col, Patches};
    let x = Tensor::arange(1f32, 7.0, &Device::Cpu)
        .unwrap()
        .reshape((1, 1, 2, 3))
        .unwrap();
    let patches = Patches {
        kernel: 2,
        stride: 1,
        padding: 0,
        ones_row: true,
    };
    // 2x3 input, 2x2 kernel: a 1x2 output; rows are taps (0,0) (0,1) (1,0) (1,1), then ones.
    let cols: Vec<Vec<f32>> = im2col(&x, patches)
        .unwrap()
        .squeeze(0)
        .unwrap()
        .to_vec2()
        .unwrap();
    assert_eq!(
        cols,
        vec![
            vec![1., 2.],
            vec![2., 3.],
            vec![4., 5.],
            vec![5., 6.],
            vec![1., 1.]
        ]
    );
    let big = Patches {
        kernel: 5,
        ..patches
    };
    assert!(im2col(&x, big).is_err());
}
