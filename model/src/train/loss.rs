//! The paper's training objective (section 3.2.5, eq. total loss) for the cost-volume branch:
//! `lambda1 * L_rec + lambda2 * L_D-rend + lambda3 * L_conf` averaged over target views, plus
//! `lambda4 * L_D-est`, with `L_rec = w_l2 * L2 + w_lpips * LPIPS`. With the volume
//! branch, the render of the joint set G = G_cv ∪ G_vol takes those terms, and two more
//! train the branch: the balanced occupancy cross-entropy against the bin's LiDAR hits, and
//! the L2 of the volume-only render on the pixels whose true point lies inside the volume
//! (as OmniScene: the rest of the image is the cost-volume branch's to explain).

use candle_core::{Result, Tensor};
use serde::{Deserialize, Serialize};

use super::data::Sample;
use super::matching::matching_loss;
use crate::lpips::Lpips;
use crate::net::volume::{occupancy_loss, VolumeOutput};
use crate::net::{Config, Prediction};
use crate::ops::{render, CH_ALPHA, CH_CONFIDENCE, CH_DEPTH, CH_R};
use renderer::RenderSettings;

/// How a depth loss measures the error against the LiDAR depth.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum DepthError {
    /// `|d - d*|` in metres (the paper's L1): far points weigh in proportion to their depth.
    #[default]
    Metric,
    /// `|d - d*| / d*` (the AbsRel the evaluation reports): every supervised pixel weighs
    /// the same, so near structure is not drowned by the far field. Its values are about
    /// 1/15 of the metric ones on the synthetic streets; scale the depth weights to match.
    Relative,
}

/// A depth-error name other than `metric` or `relative`.
#[derive(Debug, thiserror::Error)]
#[error("unknown depth error `{0}` (known: metric, relative)")]
pub struct UnknownDepthError(pub String);

impl std::str::FromStr for DepthError {
    type Err = UnknownDepthError;

    /// `metric` or `relative`, as `stereosplat research train --depth-loss` takes them.
    fn from_str(name: &str) -> std::result::Result<Self, Self::Err> {
        match name {
            "metric" => Ok(Self::Metric),
            "relative" => Ok(Self::Relative),
            other => Err(UnknownDepthError(other.to_string())),
        }
    }
}

/// Loss weights; the defaults are the paper's.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LossWeights {
    /// Weight of the image reconstruction loss (lambda1).
    pub reconstruction: f64,
    /// Weight of the rendered-depth loss (lambda2).
    pub rendered_depth: f64,
    /// Weight of the confidence loss (lambda3).
    pub confidence: f64,
    /// Weight of the estimated-depth loss (lambda4).
    pub estimated_depth: f64,
    /// Weight of the L2 term inside the reconstruction loss.
    pub l2: f64,
    /// Weight of the LPIPS term inside the reconstruction loss.
    pub lpips: f64,
    /// Sharpness of the confidence target `exp(-beta * error)` (error: mean absolute RGB
    /// error per pixel; the paper does not give beta).
    pub beta: f64,
    /// LiDAR depths beyond this are not supervised (metres; the evaluation's range).
    pub max_depth: f32,
    /// The error both depth losses average.
    pub depth_error: DepthError,
    /// Weight of the volume branch's occupancy cross-entropy (LiDAR of the whole bin).
    #[serde(default = "default_occupancy")]
    pub occupancy: f64,
    /// Weight of the volume-only render's L2 on the pixels whose true point lies in the
    /// volume.
    #[serde(default = "default_volume_render")]
    pub volume_render: f64,
    /// Weight of the matching loss on the cost volume alone (`matching`; 0, the paper's
    /// objective, leaves it out).
    #[serde(default)]
    pub matching: f64,
}

fn default_occupancy() -> f64 {
    0.05
}

fn default_volume_render() -> f64 {
    1.0
}

impl Default for LossWeights {
    fn default() -> Self {
        Self {
            reconstruction: 1.0,
            rendered_depth: 0.01,
            confidence: 0.01,
            estimated_depth: 0.05,
            l2: 1.0,
            lpips: 0.05,
            beta: 10.0,
            max_depth: 80.0,
            depth_error: DepthError::Metric,
            occupancy: default_occupancy(),
            volume_render: default_volume_render(),
            matching: 0.0,
        }
    }
}

/// The loss and its parts (the parts as plain numbers, for the log).
pub struct Losses {
    /// The total, differentiable.
    pub total: Tensor,
    /// Mean image L2 over targets.
    pub l2: f32,
    /// Mean LPIPS over targets.
    pub lpips: f32,
    /// Mean masked rendered-depth error ([`LossWeights::depth_error`]).
    pub rendered_depth: f32,
    /// Masked estimated-depth error ([`LossWeights::depth_error`]).
    pub estimated_depth: f32,
    /// Mean confidence regression error.
    pub confidence: f32,
    /// Occupancy cross-entropy (0 without the volume branch).
    pub occupancy: f32,
    /// Mean masked L2 of the volume-only render (0 without the volume branch).
    pub volume_l2: f32,
    /// Matching cross-entropy (0 when its weight is 0).
    pub matching: f32,
}

/// `sum(mask * |a - b|) / sum(mask)`, 0 when the mask is empty.
pub fn masked_l1(a: &Tensor, b: &Tensor, mask: &Tensor) -> Result<Tensor> {
    let count = mask.sum_all()?;
    let sum = ((a - b)?.abs()? * mask)?.sum_all()?;
    sum.broadcast_div(&count.maximum(1.0)?)
}

/// The masked mean of `kind`'s error of `depth` against the LiDAR depth `truth` (metres for
/// [`DepthError::Metric`], a fraction for [`DepthError::Relative`]).
pub fn depth_loss(
    depth: &Tensor,
    truth: &Tensor,
    mask: &Tensor,
    kind: DepthError,
) -> Result<Tensor> {
    match kind {
        DepthError::Metric => masked_l1(depth, truth, mask),
        DepthError::Relative => {
            // Unsupervised pixels hold 0: the floor keeps them finite, the mask drops them.
            let truth = truth.maximum(1e-3)?;
            masked_l1(&(depth / &truth)?, &truth.ones_like()?, mask)
        }
    }
}

/// The mask of supervised LiDAR pixels: a measurement in `(0, max_depth]`.
fn lidar_mask(depth: &Tensor, max_depth: f32) -> Result<Tensor> {
    let valid = depth.gt(0.0)?.mul(&depth.le(max_depth)?)?;
    valid.to_dtype(depth.dtype())
}

/// Renders every target of `sample` from `prediction` (of the network of preset `net`) and
/// scores the whole objective.
pub fn losses(
    prediction: &Prediction,
    sample: &Sample,
    lpips: &Lpips,
    weights: &LossWeights,
    settings: &RenderSettings,
    net: &Config,
) -> Result<Losses> {
    let splats = prediction.output()?.pack()?;
    let mut renders = Vec::with_capacity(sample.targets.len());
    let mut per_view = Vec::new();
    let (mut l2_sum, mut depth_sum, mut conf_sum) = (0f32, 0f32, 0f32);
    for target in &sample.targets {
        let out = render(&splats, &target.camera, settings)?;
        let rgb = out.narrow(0, CH_R, 3)?;
        let l2 = (&rgb - &target.image)?.sqr()?.mean_all()?;
        let depth = out.get(CH_DEPTH)?;
        let mask = lidar_mask(&target.depth, weights.max_depth)?;
        let d_rend = depth_loss(&depth, &target.depth, &mask, weights.depth_error)?;
        let error = (&rgb - &target.image)?.abs()?.mean(0)?.detach();
        let conf_target = (error * -weights.beta)?.exp()?;
        // Composited confidence over alpha is the confidence of what is drawn.
        let alpha = out.get(CH_ALPHA)?;
        let conf = (out.get(CH_CONFIDENCE)? - (conf_target * &alpha)?)?
            .abs()?
            .mean_all()?;
        l2_sum += l2.to_scalar::<f32>()?;
        depth_sum += d_rend.to_scalar::<f32>()?;
        conf_sum += conf.to_scalar::<f32>()?;
        per_view.push(
            ((l2 * (weights.reconstruction * weights.l2))?
                + (d_rend * weights.rendered_depth)?
                + (conf * weights.confidence)?)?,
        );
        renders.push(rgb);
    }
    let n = sample.targets.len().max(1) as f64;
    let truth: Vec<&Tensor> = sample.targets.iter().map(|t| &t.image).collect();
    let perceptual = if renders.is_empty() {
        Tensor::zeros((), splats.dtype(), splats.device())?
    } else {
        lpips
            .forward(&Tensor::stack(&renders, 0)?, &Tensor::stack(&truth, 0)?)?
            .mean_all()?
    };
    let mask = lidar_mask(&sample.input_depth, weights.max_depth)?;
    let d_est = depth_loss(
        &prediction.depth,
        &sample.input_depth,
        &mask,
        weights.depth_error,
    )?;
    let views = if per_view.is_empty() {
        Tensor::zeros((), splats.dtype(), splats.device())?
    } else {
        (Tensor::stack(&per_view, 0)?.sum_all()? / n)?
    };
    let total = ((views + (&perceptual * (weights.reconstruction * weights.lpips))?)?
        + (&d_est * weights.estimated_depth)?)?;
    // The matching term is computed only when it counts (it reads the depth back to the CPU).
    let (total, matching) = match weights.matching > 0.0 {
        true => {
            let m = matching_loss(
                &prediction.matching_logits,
                &sample.input_depth,
                net,
                weights.max_depth,
            )?;
            ((total + (&m * weights.matching)?)?, m.to_scalar::<f32>()?)
        }
        false => (total, 0.0),
    };
    let (total, occupancy, volume_l2) = match &prediction.volume {
        Some(volume) => {
            let v = volume_losses(volume, sample, settings)?;
            let total = ((total + (&v.occupancy * weights.occupancy)?)?
                + (&v.render * weights.volume_render)?)?;
            (
                total,
                v.occupancy.to_scalar::<f32>()?,
                v.render.to_scalar::<f32>()?,
            )
        }
        None => (total, 0.0, 0.0),
    };
    Ok(Losses {
        total,
        l2: l2_sum / n as f32,
        lpips: perceptual.to_scalar::<f32>()?,
        rendered_depth: depth_sum / n as f32,
        estimated_depth: d_est.to_scalar::<f32>()?,
        confidence: conf_sum / n as f32,
        occupancy,
        volume_l2,
        matching,
    })
}

/// The volume branch's own terms, scalar tensors.
struct VolumeLosses {
    occupancy: Tensor,
    render: Tensor,
}

/// Occupancy against the sample's occupied voxels over the visible ones, and the mean over
/// targets of the volume-only render's L2 on their in-volume pixels (0 for a target without
/// any, and for a branch that decoded no Gaussian).
fn volume_losses(
    volume: &VolumeOutput,
    sample: &Sample,
    settings: &RenderSettings,
) -> Result<VolumeLosses> {
    let logits = &volume.occupancy_logits;
    let zero = || Tensor::zeros((), logits.dtype(), logits.device());
    let occupancy = match &sample.occupied {
        Some(occupied) => occupancy_loss(logits, occupied, Some(&volume.visible))?,
        None => candle_core::bail!("the volume branch needs samples with occupied voxels"),
    };
    let mut terms = Vec::with_capacity(sample.targets.len());
    if volume.gaussians() > 0 {
        let splats = volume.splats.pack()?;
        for target in &sample.targets {
            let Some(mask) = &target.in_volume else {
                candle_core::bail!("the volume branch needs targets with in-volume masks");
            };
            let out = render(&splats, &target.camera, settings)?;
            let error = (out.narrow(0, CH_R, 3)? - &target.image)?
                .sqr()?
                .mean_keepdim(0)?;
            let mask = mask.unsqueeze(0)?;
            let count = mask.sum_all()?.maximum(1.0)?;
            terms.push((error * &mask)?.sum_all()?.broadcast_div(&count)?);
        }
    }
    let render = match terms.len() {
        0 => zero()?,
        n => (Tensor::stack(&terms, 0)?.sum_all()? / n as f64)?,
    };
    Ok(VolumeLosses { occupancy, render })
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    #[test]
    fn depth_losses_average_metric_and_relative_errors_over_supervised_pixels() {
        let dev = Device::Cpu;
        let depth = Tensor::new(&[2f32, 11.0, 50.0, 7.0], &dev).unwrap();
        // The last pixel has no LiDAR (0): the mask drops it, the floor keeps it finite.
        let truth = Tensor::new(&[1f32, 10.0, 40.0, 0.0], &dev).unwrap();
        let mask = lidar_mask(&truth, 80.0).unwrap();
        let value = |kind| {
            depth_loss(&depth, &truth, &mask, kind)
                .unwrap()
                .to_scalar::<f32>()
                .unwrap()
        };
        // Metric: (1 + 1 + 10) / 3 m; relative: (1/1 + 1/10 + 10/40) / 3.
        assert!((value(DepthError::Metric) - 4.0).abs() < 1e-6);
        assert!((value(DepthError::Relative) - 0.45).abs() < 1e-6);
    }
}
