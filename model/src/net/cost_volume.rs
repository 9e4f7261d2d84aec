//! The input-invariant cost volume (paper eq. for C_i): for each reference view, plane-sweep
//! correlation with each of its N nearest views by camera translation, over depth candidates
//! uniform in inverse depth, averaged over those views. Warping is bilinear sampling at the
//! projected points (`ops::grid_sample`), so any relative pose works, not only the
//! horizontal shift of a rectified pair, and 1 to K stereo pairs use the same weights.

use candle_core::{Result, Tensor};
use renderer::Camera;

use super::geometry::{nearest_views, sweep_grid};
use super::Config;
use crate::ops::grid_sample;

/// The depth candidates of a preset, nearest first, uniform in inverse depth.
pub fn candidate_depths(cfg: &Config) -> Vec<f64> {
    let (a, b) = (1.0 / cfg.near as f64, 1.0 / cfg.far as f64);
    let d = cfg.candidates.max(2);
    (0..d)
        .map(|k| 1.0 / (a + (b - a) * k as f64 / (d - 1) as f64))
        .collect()
}

/// Correlation volumes `(V, D, h, w)` of the views' features `(V, C, h, w)` (grid stride
/// `stride` in image pixels), each averaged over the view's `match_views` nearest views.
pub fn cost_volume(
    features: &Tensor,
    cameras: &[Camera],
    depths: &[f64],
    cfg: &Config,
    stride: usize,
) -> Result<Tensor> {
    let (v, c, h, w) = features.dims4()?;
    let d = depths.len();
    let scale = 1.0 / (c as f64).sqrt();
    let neighbours = nearest_views(cameras, cfg.match_views);
    let mut volumes = Vec::with_capacity(v);
    for (i, sources) in neighbours.iter().enumerate() {
        let reference = features.get(i)?.unsqueeze(1)?; // (C, 1, h, w)
        let mut sum: Option<Tensor> = None;
        for &j in sources {
            let grid = sweep_grid(
                &cameras[i],
                &cameras[j],
                depths,
                stride,
                (h, w),
                features.device(),
            )?;
            let warped = grid_sample(&features.narrow(0, j, 1)?, &grid)?.reshape((c, d, h, w))?;
            let corr = (warped.broadcast_mul(&reference)?.sum(0)? * scale)?;
            sum = Some(match sum {
                Some(s) => (s + corr)?,
                None => corr,
            });
        }
        let volume = match sum {
            Some(s) => (s / sources.len() as f64)?,
            // A single view has nothing to match: a flat volume, the heads fall back on
            // the geometry features.
            None => Tensor::zeros((d, h, w), features.dtype(), features.device())?,
        };
        volumes.push(volume);
    }
    Tensor::stack(&volumes, 0)
}
