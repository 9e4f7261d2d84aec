//! The input-invariant cost volume (paper eq. for C_i): for each reference view, plane-sweep
//! correlation with each of its N nearest views by camera translation, over depth candidates
//! uniform in inverse depth, averaged over those views. Warping is bilinear sampling at the
//! projected points (`ops::grid_sample`), so any relative pose works, not only the
//! horizontal shift of a rectified pair, and 1 to K stereo pairs use the same weights. A
//! rectified pair (every sweep point on its own row) takes the same values along rows
//! ([`super::row_correlation`]), without the warped `(C, D, h, w)` features.

use candle_core::{Result, Tensor};
use renderer::Camera;

use super::geometry::{nearest_views, sweep_points};
use super::row_correlation::{row_correlation, RowTaps};
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
/// `stride` in image pixels): the dot product of a reference pixel's feature with the
/// source's feature at each candidate depth (cosine similarity for unit features), each
/// averaged over the view's `match_views` nearest views.
pub fn cost_volume(
    features: &Tensor,
    cameras: &[Camera],
    depths: &[f64],
    cfg: &Config,
    stride: usize,
) -> Result<Tensor> {
    let (v, c, h, w) = features.dims4()?;
    let d = depths.len();
    let neighbours = nearest_views(cameras, cfg.match_views);
    let mut volumes = Vec::with_capacity(v);
    for (i, sources) in neighbours.iter().enumerate() {
        let reference = features.get(i)?; // (C, h, w)
        let mut sum: Option<Tensor> = None;
        for &j in sources {
            let points = sweep_points(&cameras[i], &cameras[j], depths, stride, (h, w));
            let corr = match RowTaps::new(&points, d, h, w) {
                Some(taps) => row_correlation(&reference, &features.get(j)?, &taps)?,
                None => {
                    let grid = Tensor::from_vec(points, (1, d * h, w, 2), features.device())?;
                    let warped =
                        grid_sample(&features.narrow(0, j, 1)?, &grid)?.reshape((c, d, h, w))?;
                    warped.broadcast_mul(&reference.unsqueeze(1)?)?.sum(0)?
                }
            };
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

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, IndexOp};

    #[test]
    fn correlation_peaks_at_the_true_depth_of_a_rectified_pair() {
        let cam = crate::net::geometry::test_camera;
        let (h, w, c) = (10, 20, 64);
        let left = Tensor::randn(0f32, 1.0, (1, c, h, w), &Device::Cpu).unwrap();
        // Disparity 2 feature pixels (8 image pixels): right(x) = left(x + 2), depth
        // fx * b / 8 = 6.25 m for a 0.5 m baseline.
        let right = left
            .narrow(3, 2, w - 2)
            .unwrap()
            .pad_with_zeros(3, 0, 2)
            .unwrap();
        let features = Tensor::cat(&[&left, &right], 0).unwrap();
        let depths = [20.0, 10.0, 6.25, 4.0];
        let volume = cost_volume(
            &features,
            &[cam(0.0), cam(0.5)],
            &depths,
            &Config::tiny(),
            4,
        )
        .unwrap();
        assert_eq!(volume.dims(), &[2, 4, h, w]);
        // Left view, pixels whose match lies inside the right view.
        let best = volume.i((0, .., .., 4..w)).unwrap().argmax(0).unwrap();
        let best: Vec<u32> = best.flatten_all().unwrap().to_vec1().unwrap();
        assert!(best.iter().all(|&b| b == 2), "{best:?}");
    }
}
