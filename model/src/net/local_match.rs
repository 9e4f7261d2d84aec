//! Local matching at the Gaussians' resolution: the cost volume matches at 1/4 resolution
//! over candidates spaced a few pixels apart on a real photograph, so its depth is only as
//! precise as that spacing. This stage samples the stereo partner's 1/2-resolution backbone
//! features at a few depths around the coarse estimate, correlates them with the view's own,
//! and turns the correlation profile into a bounded correction of the coarse inverse depth
//! (the role of the refinement stages of stereo networks, as in CasMVSNet's narrow second
//! sweep). Its last convolution starts at zero, so a network warm-started from weights
//! without it begins exactly where those weights were.

use candle_core::{Device, Module, Result, Tensor, D};
use candle_nn::VarBuilder;
use serde::{Deserialize, Serialize};

use renderer::Camera;

use super::blocks::{chain, ConvRelu};
use super::depth_head::metric_depth;
use super::geometry::{camera_to_world, nearest_views, rays};
use super::Config;
use crate::ops::{grid_sample, Conv};

/// Image pixels per pixel of the features the stage matches (the backbone's 1/2 level).
const FEATURE_STRIDE: usize = 2;
/// Source points closer to the partner camera's plane than this (metres) are not sampled.
const MIN_SOURCE_DEPTH: f64 = 1e-3;

/// The stage's sizes (`--set local_match.samples=9` switches it on).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LocalMatchConfig {
    /// Depths sampled around the coarse estimate (odd; 0: the stage is off).
    pub samples: usize,
    /// Half-width of the sampled range and bound of the correction, in candidate spacings
    /// of the cost volume.
    pub span: f32,
    /// Channels of the two convolutions that read the correlation profile.
    pub channels: usize,
}

impl Default for LocalMatchConfig {
    fn default() -> Self {
        Self {
            samples: 0,
            span: 3.0,
            channels: 16,
        }
    }
}

impl LocalMatchConfig {
    /// Whether the stage runs.
    pub fn enabled(&self) -> bool {
        self.samples > 0
    }

    /// The sampled offsets in normalised inverse depth, evenly spread over `±span`
    /// candidate spacings of a `candidates`-deep volume.
    pub fn offsets(&self, candidates: usize) -> Vec<f64> {
        let spacing = 1.0 / (candidates.max(2) - 1) as f64;
        let half = (self.samples.max(1) - 1) as f64 / 2.0;
        (0..self.samples)
            .map(|k| match half > 0.0 {
                true => (k as f64 - half) / half * self.span as f64 * spacing,
                false => 0.0,
            })
            .collect()
    }
}

/// What the stage reads.
pub struct LocalInputs<'a> {
    /// The depth head's normalised inverse depth at the Gaussians' pixels, `(V, 1, Hg, Wg)`.
    pub coarse: &'a Tensor,
    /// The backbone's 1/2-resolution features, `(V, C, ceil(H/2), ceil(W/2))`.
    pub features: &'a Tensor,
    /// The views' cameras (bin frame).
    pub cameras: &'a [Camera],
    /// Image pixels per Gaussian pixel.
    pub stride: usize,
}

/// The local matching stage.
#[derive(Clone, Debug)]
pub struct LocalMatch {
    read: Vec<ConvRelu>,
    out: Conv,
    offsets: Vec<f64>,
    bound: f64,
    cfg: Config,
}

impl LocalMatch {
    /// The stage of preset `cfg` (whose `local_match` must be enabled).
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let lm = cfg.local_match;
        if !lm.enabled() || lm.samples.is_multiple_of(2) || lm.span.is_nan() || lm.span <= 0.0 {
            candle_core::bail!(
                "local_match needs an odd number of samples and a positive span, got {} and {}",
                lm.samples,
                lm.span
            );
        }
        let c = lm.channels;
        Ok(Self {
            read: vec![
                ConvRelu::new(vb.pp("read0"), lm.samples, c, 1)?,
                ConvRelu::new(vb.pp("read1"), c, c, 1)?,
            ],
            out: Conv::zeros(vb.pp("zero_out"), (c, 1), 3, 1, 1)?,
            offsets: lm.offsets(cfg.candidates),
            bound: lm.span as f64 / (cfg.candidates.max(2) - 1) as f64,
            cfg: cfg.clone(),
        })
    }

    /// The coarse inverse depth corrected by the local match, `(V, 1, Hg, Wg)` in `[0, 1]`.
    pub fn forward(&self, x: &LocalInputs) -> Result<Tensor> {
        let profile = self.correlation(x)?;
        let delta = (self.out.forward(&chain(&self.read, &profile)?)?.tanh()? * self.bound)?;
        (x.coarse + delta)?.clamp(0f32, 1f32)
    }

    /// The correlation of each view's features with its nearest view's at the sampled
    /// depths, `(V, samples, Hg, Wg)`; zero for a view with no other view, or where the
    /// sampled point falls outside the partner's image or behind it.
    pub fn correlation(&self, x: &LocalInputs) -> Result<Tensor> {
        let (v, _, hg, wg) = x.coarse.dims4()?;
        if v != x.cameras.len() {
            candle_core::bail!("{v} views but {} cameras", x.cameras.len());
        }
        let device = x.coarse.device();
        let norm = (x.features.sqr()?.sum_keepdim(1)? + 1e-6)?.sqrt()?;
        let unit = x.features.broadcast_div(&norm)?;
        // Sampling positions follow the estimate but do not carry its gradient (as the
        // lookups of iterative stereo refiners): the correction is learned from the profile.
        let inverse = x.coarse.detach();
        let k = self.offsets.len();
        let shifted: Vec<Tensor> = self
            .offsets
            .iter()
            .map(|&o| (&inverse + o)?.clamp(0f32, 1f32))
            .collect::<Result<_>>()?;
        let depths = metric_depth(&Tensor::cat(&shifted, 1)?, &self.cfg)?; // (V, K, Hg, Wg)
        let partners = nearest_views(x.cameras, 1);
        let mut out = Vec::with_capacity(v);
        for (i, partner) in partners.iter().enumerate() {
            let own = grid_sample(
                &unit.narrow(0, i, 1)?,
                &own_grid(x.stride, (hg, wg), device)?,
            )?
            .reshape((unit.dim(1)?, 1, hg, wg))?;
            let Some(&j) = partner.first() else {
                out.push(Tensor::zeros((k, hg, wg), unit.dtype(), device)?);
                continue;
            };
            let grid = partner_grid(
                &x.cameras[i],
                &x.cameras[j],
                &depths.get(i)?,
                x.stride,
                (hg, wg),
            )?;
            let sampled =
                grid_sample(&unit.narrow(0, j, 1)?, &grid)?.reshape((unit.dim(1)?, k, hg, wg))?;
            out.push(sampled.broadcast_mul(&own)?.sum(0)?);
        }
        Tensor::stack(&out, 0)
    }
}

/// Where the Gaussians' pixels `(stride x, stride y)` lie on the 1/2-resolution grid, as a
/// `(1, Hg, Wg, 2)` sampling grid.
fn own_grid(stride: usize, (hg, wg): (usize, usize), device: &Device) -> Result<Tensor> {
    let s = stride as f32 / FEATURE_STRIDE as f32;
    let mut data = Vec::with_capacity(hg * wg * 2);
    for y in 0..hg {
        for x in 0..wg {
            data.extend([s * x as f32, s * y as f32]);
        }
    }
    Tensor::from_vec(data, (1, hg, wg, 2), device)
}

/// The points at `depths` `(K, Hg, Wg)` on the rays of `reference`'s Gaussian pixels,
/// projected onto `source`'s 1/2-resolution grid: `(1, K Hg, Wg, 2)`, NaN (sampled as zero)
/// where a point is not in front of the source. The rotation and the relative translation
/// are formed in `f64`, so cameras far from the origin lose no precision.
fn partner_grid(
    reference: &Camera,
    source: &Camera,
    depths: &Tensor,
    stride: usize,
    (hg, wg): (usize, usize),
) -> Result<Tensor> {
    let device = depths.device();
    let to_source = source.rotation.as_dmat3() * camera_to_world(reference);
    let offset =
        source.rotation.as_dmat3() * (reference.position.as_dvec3() - source.position.as_dvec3());
    let k = source.intrinsics;
    let ray = rays(reference, stride, hg, wg, device)?; // (3, P)
    let m: Vec<f32> = (0..3)
        .flat_map(|r| (0..3).map(move |c| (r, c)))
        .map(|(r, c)| to_source.col(c)[r] as f32)
        .collect();
    let turned = Tensor::from_vec(m, (3, 3), device)?.matmul(&ray)?; // (3, P)
    let d = depths.flatten_from(1)?; // (K, P)
    let axis = |a: usize, t: f64| d.broadcast_mul(&turned.get(a)?.unsqueeze(0)?)? + t;
    let (px, py, pz) = (axis(0, offset.x)?, axis(1, offset.y)?, axis(2, offset.z)?);
    let ahead = pz.ge(MIN_SOURCE_DEPTH)?;
    let safe_z = ahead.where_cond(&pz, &pz.ones_like()?)?;
    let s = FEATURE_STRIDE as f64;
    let u = (((px / &safe_z)? * (k.fx as f64 / s))? + k.cx as f64 / s)?;
    let v = (((py / &safe_z)? * (k.fy as f64 / s))? + k.cy as f64 / s)?;
    let nan = Tensor::full(f32::NAN, pz.shape(), device)?;
    let grid = Tensor::stack(
        &[ahead.where_cond(&u, &nan)?, ahead.where_cond(&v, &nan)?],
        D::Minus1,
    )?;
    grid.reshape((1, depths.dim(0)? * hg, wg, 2))
}

#[cfg(test)]
#[path = "local_match_tests.rs"]
mod tests;
