//! The cost volume's correlation for a rectified pair, along rows. When every plane-sweep
//! point of a reference pixel lies on that pixel's own row of the source (same rotation and
//! intrinsics, baseline along x), bilinear sampling is a blend of two pixels of the row, and
//! the dot product with the reference feature commutes with the blend. So the correlation
//! of every reference pixel with every source pixel of its row, one batched matrix product
//! `(h, w, C) x (h, C, w)`, is computed once and each candidate blends two of its entries.
//! Warping instead builds the `(C, D, h, w)` source features for the `D` candidates and
//! multiplies them with the reference: for the `paper` preset (128 channels, 192 candidates)
//! that product was the largest GPU cost of the network (`results/gpu/`). Same
//! values up to rounding; [`super::cost_volume`] falls back to warping for any other pose.

use candle_core::{Result, Tensor};

/// Furthest a sweep point may lie from its reference row, in pixels of the feature grid, for
/// the row path. A rectified rig lands within float rounding (about 1e-5); the blend of the
/// neighbouring row that bilinear sampling would add is that fraction of a row difference.
pub const ROW_TOLERANCE: f32 = 1e-3;

/// Where each candidate of each reference pixel reads the row correlations: two taps into
/// the flattened `(h, w, w)` correlations and their bilinear weights (zero for a tap outside
/// the image, as in `ops::grid_sample`'s zero padding), the left taps of every point, then
/// the right ones.
pub struct RowTaps {
    index: Vec<u32>,
    weight: Vec<f32>,
    shape: (usize, usize, usize),
}

impl RowTaps {
    /// The taps of `points` (`geometry::sweep_points`' layout for `d` candidates on an
    /// `h` x `w` grid), or `None` when a point is not finite or lies off its row by more than
    /// [`ROW_TOLERANCE`] (then only warping is right).
    pub fn new(points: &[f32], d: usize, h: usize, w: usize) -> Option<Self> {
        let n = d * h * w;
        if points.len() != 2 * n || h * w * w > u32::MAX as usize {
            return None;
        }
        let (mut index, mut weight) = (vec![0; 2 * n], vec![0.0; 2 * n]);
        for (k, point) in points.chunks_exact(2).enumerate() {
            let (x, y) = (k % w, (k / w) % h);
            let (gx, gy) = (point[0], point[1]);
            if !gx.is_finite() || !gy.is_finite() || (gy - y as f32).abs() > ROW_TOLERANCE {
                return None;
            }
            // ops::grid_sample's rule: a point at or beyond one pixel outside samples zero.
            let reaches = gx > -1.0 && gx < w as f32;
            let x0 = gx.floor();
            let base = ((y * w + x) * w) as u32;
            for (tap, (xi, wt)) in [(k, (x0, 1.0 - (gx - x0))), (n + k, (x0 + 1.0, gx - x0))] {
                if reaches && xi >= 0.0 && xi <= (w - 1) as f32 {
                    (index[tap], weight[tap]) = (base + xi as u32, wt);
                }
            }
        }
        Some(Self {
            index,
            weight,
            shape: (d, h, w),
        })
    }
}

/// Correlations `(D, h, w)` of `reference` `(C, h, w)` with `source` `(C, h, w)` at `taps`:
/// the value warping gives (`grid_sample` of the source, times the reference, summed over
/// channels). Differentiable with respect to both feature maps.
pub fn row_correlation(reference: &Tensor, source: &Tensor, taps: &RowTaps) -> Result<Tensor> {
    let (d, h, w) = taps.shape;
    let device = reference.device();
    let rows = reference.permute((1, 2, 0))?.contiguous()?; // (h, w, C)
    let columns = source.permute((1, 0, 2))?.contiguous()?; // (h, C, w)
    let all = rows.matmul(&columns)?.flatten_all()?; // (h w w)
    let n = 2 * d * h * w;
    let index = Tensor::from_slice(&taps.index, n, device)?;
    let weight = Tensor::from_slice(&taps.weight, n, device)?.to_dtype(all.dtype())?;
    all.index_select(&index, 0)?
        .mul(&weight)?
        .reshape((2, d, h, w))?
        .sum(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::geometry::{sweep_points, test_camera};
    use crate::ops::grid_sample;
    use candle_core::{DType, Device, Var};

    /// Warping's correlation, the reference the row path must equal.
    fn warped(reference: &Tensor, source: &Tensor, points: Vec<f32>, d: usize) -> Tensor {
        let (c, h, w) = reference.dims3().unwrap();
        let grid = Tensor::from_vec(points, (1, d * h, w, 2), &Device::Cpu)
            .and_then(|g| g.to_dtype(DType::F64))
            .unwrap();
        grid_sample(&source.unsqueeze(0).unwrap(), &grid)
            .unwrap()
            .reshape((c, d, h, w))
            .unwrap()
            .broadcast_mul(&reference.unsqueeze(1).unwrap())
            .unwrap()
            .sum(0)
            .unwrap()
    }

    fn max_abs(t: &Tensor) -> f64 {
        t.abs().and_then(|a| a.max_all()?.to_scalar()).unwrap()
    }

    #[test]
    fn rows_give_warpings_values_and_gradients_from_beyond_the_image_to_infinity() {
        let (c, h, w) = (16, 6, 20);
        // Depths whose disparity (100 * 0.5 / d / 4 feature pixels) is far beyond the image,
        // at a pixel edge, fractional, sub-pixel, and zero (a point at infinity's row).
        let depths = [0.3, 1.0, 6.25, 7.3, 100.0, 1e12];
        let (left, right) = (test_camera(0.0), test_camera(0.5));
        let device = Device::Cpu;
        let features = || {
            Tensor::randn(0.0, 1.0, (c, h, w), &device)
                .and_then(|t| Var::from_tensor(&t.to_dtype(DType::F64)?))
                .unwrap()
        };
        let (reference, source) = (features(), features());
        let points = sweep_points(&left, &right, &depths, 4, (h, w));
        let taps = RowTaps::new(&points, depths.len(), h, w).expect("a rectified pair");
        let rows = row_correlation(&reference, &source, &taps).unwrap();
        let warp = warped(&reference, &source, points, depths.len());
        assert_eq!(rows.dims(), &[depths.len(), h, w]);
        let scale = max_abs(&warp);
        assert!(scale > 1.0);
        let diff = max_abs(&(&rows - &warp).unwrap()) / scale;
        assert!(diff < 1e-6, "forward differs by {diff:e}");
        // Candidates beyond the image correlate with nothing.
        assert_eq!(max_abs(&rows.get(0).unwrap()), 0.0);

        let weights = Tensor::randn(0.0, 1.0, rows.dims(), &device)
            .unwrap()
            .to_dtype(DType::F64)
            .unwrap();
        let grads_rows = (&rows * &weights)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        let grads_warp = (&warp * &weights)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        for var in [&reference, &source] {
            let (a, b) = (grads_rows.get(var).unwrap(), grads_warp.get(var).unwrap());
            let diff = max_abs(&(a - b).unwrap()) / max_abs(b);
            assert!(diff < 1e-6, "gradient differs by {diff:e}");
            assert!(a
                .flatten_all()
                .unwrap()
                .to_vec1::<f64>()
                .unwrap()
                .iter()
                .all(|v| v.is_finite()));
        }
    }

    #[test]
    fn any_pose_but_a_rectified_one_is_left_to_warping() {
        let (h, w) = (6, 20);
        let depths = [2.0, 10.0];
        let left = test_camera(0.0);
        let mut above = test_camera(0.0);
        above.position.y = 0.5;
        let mut turned = test_camera(0.5);
        turned.rotation = glam::Mat3::from_rotation_y(0.05) * turned.rotation;
        for source in [above, turned] {
            let points = sweep_points(&left, &source, &depths, 4, (h, w));
            assert!(RowTaps::new(&points, depths.len(), h, w).is_none());
        }
        // Behind the source camera: NaN points.
        let points = vec![f32::NAN; 2 * depths.len() * h * w];
        assert!(RowTaps::new(&points, depths.len(), h, w).is_none());
    }
}
