//! The matching loss: supervision of the cost volume itself. The depth head adds the
//! U-Net's bounded logits to the correlation times a learned temperature, and trained on
//! the render and depth losses alone the network let the U-Net's street-trained priors
//! decide: its correlation alone (winner-take-all) has an AbsRel of 0.40 on held-out
//! generated streets where SGM has 0.21, and on a real photograph shifted against itself it
//! is no better, so such a network fails on real pairs,
//! where the street-trained priors are wrong. This loss
//! asks the matching term alone to put its mass on the LiDAR depth, so the features must
//! match and the temperature must be sharp enough for matching to count.

use candle_core::{Result, Tensor};

use crate::net::{every_nth_pixel, normalised_inverse, Config, COST_STRIDE};

/// Cross-entropy of the depth head's matching logits `(V, D, h, w)` against a two-hot
/// target: the LiDAR depth's place between the two candidates around it, in normalised
/// inverse depth (depths beyond the candidate range go to the end candidates). Averaged
/// over the 1/4-resolution pixels with a measurement in `(0, max_depth]`; 0 when there
/// are none. `input_depth` is the views' LiDAR depth at the Gaussians' pixels (stride
/// `cfg.gaussian_stride`, which must divide the cost volume's).
pub fn matching_loss(
    logits: &Tensor,
    input_depth: &Tensor,
    cfg: &Config,
    max_depth: f32,
) -> Result<Tensor> {
    let (v, d, h, w) = logits.dims4()?;
    let g = cfg.gaussian_stride.max(1);
    if !COST_STRIDE.is_multiple_of(g) {
        candle_core::bail!(
            "the matching loss needs a Gaussian stride dividing {COST_STRIDE}, got {g}"
        );
    }
    let depth = every_nth_pixel(input_depth, COST_STRIDE / g)?;
    if depth.dims4()? != (v, 1, h, w) {
        candle_core::bail!(
            "depth {:?} does not cover the cost volume {:?}",
            depth.dims(),
            logits.dims()
        );
    }
    let zero = || Tensor::zeros((), logits.dtype(), logits.device());
    if d < 2 {
        return zero();
    }
    let depth: Vec<f32> = depth.flatten_all()?.to_vec1()?;
    let p = h * w;
    let mut target = vec![0f32; v * d * p];
    let mut mask = vec![0f32; v * p];
    for view in 0..v {
        for (i, &z) in depth[view * p..(view + 1) * p].iter().enumerate() {
            if !(z > 0.0 && z <= max_depth) {
                continue;
            }
            // Candidate k sits at normalised inverse depth 1 - k / (D - 1).
            let u = normalised_inverse(z as f64, cfg).clamp(0.0, 1.0);
            let f = (1.0 - u) * (d - 1) as f64;
            let lo = (f.floor() as usize).min(d - 2);
            let frac = (f - lo as f64) as f32;
            target[(view * d + lo) * p + i] = 1.0 - frac;
            target[(view * d + lo + 1) * p + i] = frac;
            mask[view * p + i] = 1.0;
        }
    }
    let count: f32 = mask.iter().sum();
    if count == 0.0 {
        return zero();
    }
    let device = logits.device();
    let target = Tensor::from_vec(target, (v, d, h, w), device)?;
    let mask = Tensor::from_vec(mask, (v, h, w), device)?;
    let log_p = candle_nn::ops::log_softmax(logits, 1)?;
    let ce = (target * log_p)?.sum(1)?.neg()?;
    (ce * mask)?.sum_all()? / count as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    /// `tiny` (32 candidates, 1 to 100 m, Gaussians every 2 pixels).
    fn cfg() -> Config {
        Config::tiny()
    }

    #[test]
    fn a_volume_peaked_at_the_truth_scores_lower_than_a_flat_or_wrong_one() {
        let cfg = cfg();
        let (h, w) = (3, 4);
        // 10 m everywhere: normalised inverse (0.1 - 0.01) / 0.99, between candidates.
        let depth = Tensor::full(10f32, (1, 1, 2 * h, 2 * w), &Device::Cpu).unwrap();
        let u = (0.1 - 0.01) / 0.99;
        let f = (1.0 - u) * 31.0;
        let peaked = |at: f64| {
            let v: Vec<f32> = (0..32)
                .flat_map(|k| {
                    let logit = -20.0 * (k as f64 - at).powi(2);
                    std::iter::repeat_n(logit as f32, h * w)
                })
                .collect();
            Tensor::from_vec(v, (1, 32, h, w), &Device::Cpu).unwrap()
        };
        let score = |t: &Tensor| {
            matching_loss(t, &depth, &cfg, 80.0)
                .unwrap()
                .to_scalar::<f32>()
                .unwrap()
        };
        let flat = Tensor::zeros((1, 32, h, w), candle_core::DType::F32, &Device::Cpu).unwrap();
        let right = score(&peaked(f));
        assert!(right < score(&flat), "{right} {}", score(&flat));
        assert!(right < score(&peaked(f + 3.0)));
        // The flat volume's cross-entropy is ln 32 whatever the target.
        assert!((score(&flat) - 32f32.ln()).abs() < 1e-4);
    }

    #[test]
    fn extremes_and_missing_depth_stay_finite() {
        let cfg = cfg();
        let (h, w) = (2, 3);
        // Unsupervised (0), nearer than the nearest candidate, beyond the farthest, beyond
        // max_depth, and a huge logit volume.
        for z in [0f32, 1e-4, 0.5, 150.0, 1e6, 79.9] {
            let depth = Tensor::full(z, (2, 1, 2 * h, 2 * w), &Device::Cpu).unwrap();
            for scale in [0f32, 1.0, 1e4] {
                let logits = Var::from_tensor(
                    &(Tensor::randn(0f32, 1.0, (2, 32, h, w), &Device::Cpu).unwrap()
                        * scale as f64)
                        .unwrap(),
                )
                .unwrap();
                let loss = matching_loss(logits.as_tensor(), &depth, &cfg, 80.0).unwrap();
                let value = loss.to_scalar::<f32>().unwrap();
                assert!(
                    value.is_finite() && value >= 0.0,
                    "z {z} scale {scale}: {value}"
                );
                if z == 0.0 || z > 80.0 {
                    assert_eq!(value, 0.0);
                }
                let grad = loss.backward().unwrap();
                let g: Vec<f32> = grad
                    .get(&logits)
                    .map(|g| g.flatten_all().unwrap().to_vec1().unwrap())
                    .unwrap_or_default();
                assert!(g.iter().all(|x| x.is_finite()), "z {z} scale {scale}");
            }
        }
    }

    #[test]
    fn a_stride_that_does_not_divide_the_volume_is_an_error() {
        let cfg = Config::tiny()
            .with_settings(&["gaussian_stride=3"])
            .unwrap();
        let depth = Tensor::ones((1, 1, 4, 4), candle_core::DType::F32, &Device::Cpu).unwrap();
        let logits = Tensor::zeros((1, 32, 3, 3), candle_core::DType::F32, &Device::Cpu).unwrap();
        assert!(matching_loss(&logits, &depth, &cfg, 80.0).is_err());
    }
}
