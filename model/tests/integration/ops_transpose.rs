//! `model::ops::transpose_last2`: values against candle's own transpose for shapes that do
//! and do not fill whole 64 x 64 tiles, strided and empty inputs, both dtypes; the gradient against
//! central finite differences in f64.

use candle_core::{DType, Device, Tensor, Var};
use model::ops::transpose_last2;

fn ramp(shape: (usize, usize, usize), dtype: DType) -> Tensor {
    let n = shape.0 * shape.1 * shape.2;
    let v: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    Tensor::from_vec(v, shape, &Device::Cpu)
        .unwrap()
        .to_dtype(dtype)
        .unwrap()
}

fn max_diff(a: &Tensor, b: &Tensor) -> f64 {
    (a - b)
        .unwrap()
        .abs()
        .unwrap()
        .to_dtype(DType::F64)
        .unwrap()
        .max_all()
        .unwrap()
        .to_scalar::<f64>()
        .unwrap()
}

#[test]
fn equals_candles_transpose() {
    for dtype in [DType::F32, DType::F64] {
        for shape in [
            (1, 1, 1),
            (2, 52, 100),
            (3, 33, 65),
            (2, 130, 70),
            (1, 64, 3456),
        ] {
            let x = ramp(shape, dtype);
            let got = transpose_last2(&x).unwrap();
            assert_eq!(got.dims(), [shape.0, shape.2, shape.1]);
            assert_eq!(
                max_diff(&got, &x.transpose(1, 2).unwrap()),
                0.0,
                "{shape:?}"
            );
        }
        // A strided input (a transposed view) and an empty one.
        let x = ramp((2, 40, 70), dtype).transpose(1, 2).unwrap();
        let got = transpose_last2(&x).unwrap();
        assert_eq!(max_diff(&got, &ramp((2, 40, 70), dtype)), 0.0);
        let empty = Tensor::zeros((2, 0, 5), dtype, &Device::Cpu).unwrap();
        assert_eq!(transpose_last2(&empty).unwrap().dims(), [2, 5, 0]);
    }
    assert!(transpose_last2(&ramp((2, 3, 4), DType::F32).flatten_all().unwrap()).is_err());
}

#[test]
fn gradient_matches_finite_differences() {
    let x = Var::from_tensor(&ramp((2, 5, 7), DType::F64)).unwrap();
    let w = ramp((2, 7, 5), DType::F64).sqr().unwrap();
    let loss = |x: &Tensor| {
        (transpose_last2(x).unwrap() * &w)
            .unwrap()
            .sum_all()
            .unwrap()
    };
    let grads = loss(x.as_tensor()).backward().unwrap();
    let g: Vec<f64> = grads
        .get(x.as_tensor())
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    let base: Vec<f64> = x.as_tensor().flatten_all().unwrap().to_vec1().unwrap();
    let eps = 1e-6;
    for i in 0..base.len() {
        let at = |d: f64| {
            let mut v = base.clone();
            v[i] += d;
            let t = Tensor::from_vec(v, (2, 5, 7), &Device::Cpu).unwrap();
            loss(&t).to_scalar::<f64>().unwrap()
        };
        let numeric = (at(eps) - at(-eps)) / (2.0 * eps);
        assert!((numeric - g[i]).abs() < 1e-8, "{i}: {numeric} vs {}", g[i]);
    }
}
