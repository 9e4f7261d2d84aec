//! The light 2D U-Net depth head: cost volume and view features in, a softmax over the depth
//! candidates out (its expectation in inverse depth is the depth, its peak the matching
//! confidence). The Gaussian heads refine it at the Gaussians' resolution.

use candle_core::{Module, Result, Tensor, D};
use candle_nn::VarBuilder;

use crate::ops::Conv;

use super::blocks::{conv, ConvRelu, ResBlock};
use super::Config;
use crate::ops::upsample_bilinear;

/// The temperature the correlation starts with.
const INITIAL_TEMPERATURE: f64 = 10.0;
/// An extra correlation's weight is this times its variable: AdamW moves a variable by
/// about the learning rate per step, so unscaled it could not reach the temperature's size
/// (3 to 10) within a run of a few thousand steps at 5e-4.
const EXTRA_WEIGHT_SCALE: f64 = 10.0;

/// Correlations beside the view features' own that join the matching term, each at its own
/// learned weight starting from zero (so weights trained without them load and start
/// unchanged); each is `(V, D, h, w)` like the cost volume, and ignored unless the preset
/// switches it on.
#[derive(Clone, Copy, Default)]
pub struct ExtraCosts<'a> {
    /// With `census_matching`: the aggregated census correlation of the grey images.
    pub census: Option<&'a Tensor>,
    /// With `sgm_guidance`: the hints' bumps ([`super::guidance`]), added as they are.
    pub guidance: Option<&'a Tensor>,
}

/// The head's estimate at 1/4 resolution.
pub struct CoarseDepth {
    /// Softmax over the candidates, `(V, D, h, w)`.
    pub probabilities: Tensor,
    /// Expected normalised inverse depth in `[0, 1]` (0 = far, 1 = near), `(V, 1, h, w)`.
    pub inverse: Tensor,
    /// The matching term of the logits: the correlation times the temperature, `(V, D, h, w)`.
    pub matching: Tensor,
}

/// The U-Net over (cost volume, features).
#[derive(Clone, Debug)]
pub struct DepthHead {
    enter: ConvRelu,
    down: ConvRelu,
    bottom: ResBlock,
    up: ConvRelu,
    logits: Conv,
    /// Log of the factor on the cosine-similarity volume before the softmax (learned, from
    /// 10: sharp enough that matching decides the first steps).
    log_temperature: Tensor,
    /// Normalised inverse depth of each candidate (1 = nearest), `(1, D, 1, 1)`.
    candidates: Tensor,
    /// The preset's bound on the U-Net's logits.
    logit_bound: Option<f32>,
    /// With `census_matching`: the learned weight of the census correlation in the matching
    /// term, over [`EXTRA_WEIGHT_SCALE`] (from 0).
    census_weight: Option<Tensor>,
}

/// The variable `name`, starting at zero, when `on`.
fn extra_weight(vb: &VarBuilder, on: bool, name: &str) -> Result<Option<Tensor>> {
    match on {
        true => Ok(Some(vb.get_with_hints(
            1,
            name,
            candle_nn::Init::Const(0.0),
        )?)),
        false => Ok(None),
    }
}

impl DepthHead {
    /// Built for the preset's candidates and U-Net width on `cost_channels` features.
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let (d, u) = (cfg.candidates, cfg.unet_channels);
        let steps: Vec<f32> = (0..d)
            .map(|k| 1.0 - k as f32 / (d - 1).max(1) as f32)
            .collect();
        Ok(Self {
            enter: ConvRelu::new(vb.pp("enter"), d + cfg.cost_channels, u, 1)?,
            down: ConvRelu::new(vb.pp("down"), u, 2 * u, 2)?,
            bottom: ResBlock::new(vb.pp("bottom"), 2 * u)?,
            up: ConvRelu::new(vb.pp("up"), 3 * u, u, 1)?,
            logits: conv(vb.pp("logits"), u, d, 3, 1)?,
            log_temperature: vb.get_with_hints(
                1,
                "log_temperature",
                candle_nn::Init::Const(INITIAL_TEMPERATURE.ln()),
            )?,
            candidates: Tensor::from_vec(steps, (1, d, 1, 1), vb.device())?,
            logit_bound: cfg.depth_logit_bound,
            census_weight: extra_weight(&vb, cfg.census_matching, "zero_census_weight")?,
        })
    }

    /// Cost volume `(V, D, h, w)` and features `(V, Cc, h, w)` to the coarse depth. The
    /// U-Net's logits are added to the correlation times the temperature, so matching drives
    /// the softmax from the first step and the U-Net learns the corrections. The `extra`
    /// correlations the preset switches on join the matching term at their learned weights.
    pub fn forward(
        &self,
        cost: &Tensor,
        features: &Tensor,
        extra: ExtraCosts,
    ) -> Result<CoarseDepth> {
        let (_, _, h, w) = cost.dims4()?;
        let x1 = self.enter.forward(&Tensor::cat(&[cost, features], 1)?)?;
        let x2 = self.bottom.forward(&self.down.forward(&x1)?)?;
        let up = upsample_bilinear(&x2, h, w)?;
        let x = self.up.forward(&Tensor::cat(&[&up, &x1], 1)?)?;
        let mut sharpened =
            cost.broadcast_mul(&self.log_temperature.exp()?.reshape((1, 1, 1, 1))?)?;
        if let (Some(weight), Some(census)) = (&self.census_weight, extra.census) {
            let weight = (weight * EXTRA_WEIGHT_SCALE)?.reshape((1, 1, 1, 1))?;
            sharpened = (sharpened + census.broadcast_mul(&weight)?)?;
        }
        if let Some(guidance) = extra.guidance {
            sharpened = (sharpened + guidance)?;
        }
        let unet = self.logits.forward(&x)?;
        let unet = match self.logit_bound {
            Some(b) => ((unet / b as f64)?.tanh()? * b as f64)?,
            None => unet,
        };
        let logits = (unet + &sharpened)?;
        let probabilities = candle_nn::ops::softmax(&logits, 1)?;
        let inverse = probabilities
            .broadcast_mul(&self.candidates)?
            .sum_keepdim(1)?;
        Ok(CoarseDepth {
            probabilities,
            inverse,
            matching: sharpened,
        })
    }
}

/// Normalised inverse depth of a metric `depth` (1 at `near`, 0 at `far`, outside `[0, 1]`
/// beyond them): the inverse of `metric_depth`, where a depth falls among the candidates.
pub fn normalised_inverse(depth: f64, cfg: &Config) -> f64 {
    let (a, b) = (1.0 / cfg.near as f64, 1.0 / cfg.far as f64);
    (1.0 / depth - b) / (a - b)
}

/// Metric depth of a normalised inverse depth (1 = `near`, 0 = `far`).
pub fn metric_depth(inverse: &Tensor, cfg: &Config) -> Result<Tensor> {
    let (a, b) = (1.0 / cfg.near as f64, 1.0 / cfg.far as f64);
    ((inverse * (a - b))? + b)?.recip()
}

/// The matching confidence: the softmax's peak, `(V, 1, h, w)`.
pub fn peak(probabilities: &Tensor) -> Result<Tensor> {
    probabilities.max_keepdim(D::Minus(3))
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{DType, Device, Var};
    use candle_nn::VarMap;

    fn head() -> (DepthHead, VarMap, Config) {
        let cfg = Config {
            census_matching: true,
            ..Config::tiny()
        };
        let varmap = VarMap::new();
        let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
        (DepthHead::new(vb, &cfg).unwrap(), varmap, cfg)
    }

    fn inputs(cfg: &Config, scale: f64) -> (Tensor, Tensor, Tensor) {
        let (d, c) = (cfg.candidates, cfg.cost_channels);
        let cost = (Tensor::rand(-1f32, 1.0, (2, d, 4, 8), &Device::Cpu).unwrap() * scale).unwrap();
        let features = Tensor::randn(0f32, 1.0, (2, c, 4, 8), &Device::Cpu).unwrap();
        let census =
            (Tensor::rand(-1f32, 1.0, (2, d, 4, 8), &Device::Cpu).unwrap() * scale).unwrap();
        (cost, features, census)
    }

    #[test]
    fn the_census_correlation_starts_at_zero_weight() {
        let (head, _vars, cfg) = head();
        let (cost, features, census) = inputs(&cfg, 1.0);
        let with = head
            .forward(
                &cost,
                &features,
                ExtraCosts {
                    census: Some(&census),
                    ..ExtraCosts::default()
                },
            )
            .unwrap();
        let without = head
            .forward(&cost, &features, ExtraCosts::default())
            .unwrap();
        let diff = (with.probabilities - without.probabilities)
            .unwrap()
            .abs()
            .unwrap()
            .max_all()
            .unwrap();
        assert_eq!(diff.to_scalar::<f32>().unwrap(), 0.0);
    }

    #[test]
    fn the_matching_term_stays_finite_at_the_extremes() {
        let (head, varmap, cfg) = head();
        for (name, var) in varmap.data().lock().unwrap().iter() {
            if name.contains("zero_census_weight") {
                var.set(&Tensor::new(&[1e3f32], &Device::Cpu).unwrap())
                    .unwrap();
            }
        }
        for scale in [0.0, 1.0, 1e4] {
            let (cost, features, census) = inputs(&cfg, scale);
            let census = Var::from_tensor(&census).unwrap();
            let out = head
                .forward(
                    &cost,
                    &features,
                    ExtraCosts {
                        census: Some(census.as_tensor()),
                        ..ExtraCosts::default()
                    },
                )
                .unwrap();
            let p: Vec<f32> = out.probabilities.flatten_all().unwrap().to_vec1().unwrap();
            assert!(p.iter().all(|x| x.is_finite()), "scale {scale}");
            let inverse: Vec<f32> = out.inverse.flatten_all().unwrap().to_vec1().unwrap();
            assert!(
                inverse.iter().all(|x| (0.0..=1.0 + 1e-5).contains(x)),
                "scale {scale}"
            );
            let grads = out.inverse.sum_all().unwrap().backward().unwrap();
            let g: Vec<f32> = grads
                .get(&census)
                .unwrap()
                .flatten_all()
                .unwrap()
                .to_vec1()
                .unwrap();
            assert!(g.iter().all(|x| x.is_finite()), "scale {scale}");
        }
    }
}
