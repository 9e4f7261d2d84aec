//! What the volume-branch tests share: small volumes, seeded random tensors, a
//! central-finite-difference gradient check in `f64`, and finiteness checks.

use candle_core::{backprop::GradStore, DType, Device, Tensor, Var};
use model::net::volume::VolumeConfig;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A volume small enough for finite differences: 3 x 2 x 4 cells of 1 m from the origin,
/// 4 channels, 2 Gaussians per voxel, 5 voxels decoded.
pub fn tiny_volume() -> VolumeConfig {
    VolumeConfig {
        range_min: [0.0, 0.0, 0.0],
        range_max: [3.0, 2.0, 4.0],
        cells: [3, 2, 4],
        channels: 4,
        gaussians_per_voxel: 2,
        top_k: 5,
        ..VolumeConfig::tiny()
    }
}

/// A seeded generator.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// Uniform values in `[lo, hi)` as an `f64` tensor of `shape` (all `lo` when `hi <= lo`).
pub fn uniform(rng: &mut ChaCha8Rng, shape: &[usize], lo: f64, hi: f64) -> Tensor {
    let n = shape.iter().product();
    let v: Vec<f64> = (0..n)
        .map(|_| {
            if hi > lo {
                rng.random_range(lo..hi)
            } else {
                lo
            }
        })
        .collect();
    Tensor::from_vec(v, shape, &Device::Cpu).unwrap()
}

/// The values of `t` as `f64`.
pub fn values(t: &Tensor) -> Vec<f64> {
    t.to_dtype(DType::F64)
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap()
}

/// Panics naming `what` unless every value of `t` is finite.
pub fn assert_finite(t: &Tensor, what: &str) {
    let v = values(t);
    assert!(v.iter().all(|x| x.is_finite()), "{what}: {v:?}");
}

/// Every gradient `grads` holds for `vars` is finite.
pub fn assert_finite_grads(grads: &GradStore, vars: &[&Var], what: &str) {
    for (i, var) in vars.iter().enumerate() {
        if let Some(g) = grads.get(var.as_tensor()) {
            assert_finite(g, &format!("{what}: gradient of variable {i}"));
        }
    }
}

/// Checks the gradient `loss` gets by backpropagation with respect to each of `vars`
/// against central finite differences (step 1e-6, `f64`), at up to `per_var` entries of
/// each (spread over the tensor). A variable the loss does not reach must have a zero
/// difference quotient. Returns the largest absolute error seen.
pub fn check_gradients(vars: &[(&str, &Var)], per_var: usize, loss: &dyn Fn() -> Tensor) -> f64 {
    let eval = || values(&loss())[0];
    let grads = loss().backward().unwrap();
    let eps = 1e-6;
    let mut worst = 0f64;
    for (name, var) in vars {
        let base = values(var.as_tensor());
        let shape = var.as_tensor().dims().to_vec();
        let analytic = grads
            .get(var.as_tensor())
            .map(values)
            .unwrap_or_else(|| vec![0.0; base.len()]);
        let step = (base.len() / per_var).max(1);
        for i in (0..base.len()).step_by(step) {
            let at = |delta: f64| {
                let mut v = base.clone();
                v[i] += delta;
                var.set(&Tensor::from_vec(v, shape.as_slice(), &Device::Cpu).unwrap())
                    .unwrap();
                eval()
            };
            let numeric = (at(eps) - at(-eps)) / (2.0 * eps);
            var.set(&Tensor::from_vec(base.clone(), shape.as_slice(), &Device::Cpu).unwrap())
                .unwrap();
            let err = (numeric - analytic[i]).abs();
            assert!(
                err <= 1e-5 * (1.0 + numeric.abs()),
                "{name}[{i}]: backprop {} vs finite difference {numeric}",
                analytic[i]
            );
            worst = worst.max(err);
        }
    }
    worst
}
