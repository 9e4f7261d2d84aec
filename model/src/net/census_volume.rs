//! A fixed matching cost beside the learned one (`census_matching`), for matching that
//! transfers from generated streets to real photographs: soft census descriptors of the grey
//! images at the cost volume's resolution, correlated by the same plane sweep as the
//! features, then averaged over a 3x3 window of cells, as local stereo matchers aggregate.
//! At full resolution a census decorrelates within a pixel or two while the candidates lie
//! about 4 pixels apart on a near scene, so it scores worse there than at 1/4. A census
//! compares each pixel only with its neighbours, so it is blind to the gain, offset and
//! texture statistics that differ between the generated streets and real cameras; the
//! learned features are not, and matched poorly on real pairs. Flat regions give
//! descriptors near zero and so no matching evidence, where the depth head's priors decide.

use candle_core::{Result, Tensor};
use renderer::Camera;

use super::cost_volume::cost_volume;
use super::Config;

/// Half width of the square census window (5x5, 24 neighbours).
const CENSUS_RADIUS: usize = 2;
/// Grey-level difference (images in `[0, 1]`) at which a comparison is 76% decided:
/// `tanh(diff / SOFTNESS)`, so sensor noise of a few grey levels stays soft, not a coin flip.
const SOFTNESS: f64 = 0.02;
/// Half width of the aggregation window, in cost-volume cells (3x3).
const AGGREGATE_RADIUS: usize = 1;

/// Soft census descriptors of `images` `(V, 3, H, W)` in `[0, 1]`: for each of the 24
/// neighbours of a 5x5 window, `tanh((neighbour - centre) / SOFTNESS)` of the Rec. 601 luma
/// (borders replicated), scaled so that the dot product of two descriptors is the mean of
/// the comparisons' products, in `[-1, 1]`. `(V, 24, H, W)`.
pub fn census_descriptors(images: &Tensor) -> Result<Tensor> {
    let (_, _, h, w) = images.dims4()?;
    let luma = Tensor::new(&[0.299f32, 0.587, 0.114], images.device())?
        .to_dtype(images.dtype())?
        .reshape((1, 3, 1, 1))?;
    let grey = images.broadcast_mul(&luma)?.sum_keepdim(1)?;
    let r = CENSUS_RADIUS;
    let padded = grey.pad_with_same(2, r, r)?.pad_with_same(3, r, r)?;
    let n = (2 * r + 1) * (2 * r + 1) - 1;
    let scale = 1.0 / (n as f64).sqrt();
    let mut bits = Vec::with_capacity(n);
    for dy in 0..=2 * r {
        for dx in 0..=2 * r {
            if (dy, dx) == (r, r) {
                continue;
            }
            let neighbour = padded.narrow(2, dy, h)?.narrow(3, dx, w)?;
            bits.push((((neighbour - &grey)? / SOFTNESS)?.tanh()? * scale)?);
        }
    }
    Tensor::cat(&bits, 1)
}

/// The census correlation volume `(V, D, ceil(H/stride), ceil(W/stride))` of `images`
/// `(V, 3, H, W)` at the candidate `depths`: the images averaged over the
/// `(stride + 1)`-pixel square centred on each cell of the `stride` grid (pixel
/// `stride * x`, the cell's ray), their census descriptors correlated with each view's
/// `match_views` nearest views (as [`cost_volume`]), and averaged over 3x3 cells.
pub fn census_volume(
    images: &Tensor,
    cameras: &[Camera],
    depths: &[f64],
    cfg: &Config,
    stride: usize,
) -> Result<Tensor> {
    let r = stride / 2;
    let cells = images
        .pad_with_same(2, r, r)?
        .pad_with_same(3, r, r)?
        .avg_pool2d_with_stride((2 * r + 1, 2 * r + 1), (stride, stride))?;
    let per_cell = cost_volume(&census_descriptors(&cells)?, cameras, depths, cfg, stride)?;
    let a = AGGREGATE_RADIUS;
    per_cell
        .pad_with_same(2, a, a)?
        .pad_with_same(3, a, a)?
        .avg_pool2d_with_stride((2 * a + 1, 2 * a + 1), (1, 1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, IndexOp};

    /// A textured image `(1, 3, h, w)`: a seeded pattern with gain `gain` and offset `offset`.
    fn texture(h: usize, w: usize, gain: f32, offset: f32) -> Tensor {
        let data: Vec<f32> = (0..3 * h * w)
            .map(|i| {
                let p = i % (h * w);
                let v = ((p * 2654435761usize) >> 7) % 97;
                (offset + gain * v as f32 / 97.0).clamp(0.0, 1.0)
            })
            .collect();
        Tensor::from_vec(data, (1, 3, h, w), &Device::Cpu).unwrap()
    }

    #[test]
    fn the_census_volume_peaks_at_the_true_depth_under_a_gain_change() {
        let cam = crate::net::geometry::test_camera;
        let (h, w) = (40, 80);
        let left = texture(h, w, 0.8, 0.1);
        // Disparity 8 image pixels (fx 100, baseline 0.5 m: 6.25 m), the right camera
        // darker and offset: right(x) = 0.5 left(x + 8) + 0.2.
        let right = ((left
            .narrow(3, 8, w - 8)
            .unwrap()
            .pad_with_same(3, 0, 8)
            .unwrap()
            * 0.5)
            .unwrap()
            + 0.2)
            .unwrap();
        let images = Tensor::cat(&[&left, &right], 0).unwrap();
        let depths = [20.0, 10.0, 6.25, 4.0];
        let volume =
            census_volume(&images, &[cam(0.0), cam(0.5)], &depths, &Config::tiny(), 4).unwrap();
        assert_eq!(volume.dims(), &[2, 4, 10, 20]);
        let best = volume.i((0, .., 1..9, 3..17)).unwrap().argmax(0).unwrap();
        let best: Vec<u32> = best.flatten_all().unwrap().to_vec1().unwrap();
        assert!(best.iter().all(|&b| b == 2), "{best:?}");
    }

    #[test]
    fn flat_black_and_saturated_images_give_no_matching_evidence() {
        let cam = crate::net::geometry::test_camera;
        for value in [0f32, 0.5, 1.0] {
            let images = Tensor::full(value, (2, 3, 40, 80), &Device::Cpu).unwrap();
            let volume = census_volume(
                &images,
                &[cam(0.0), cam(0.5)],
                &[20.0, 5.0],
                &Config::tiny(),
                4,
            )
            .unwrap();
            let max = volume.abs().unwrap().max_all().unwrap();
            assert_eq!(max.to_scalar::<f32>().unwrap(), 0.0, "value {value}");
        }
    }

    #[test]
    fn the_census_volume_stays_finite_and_bounded_at_the_extremes() {
        let cam = crate::net::geometry::test_camera;
        let images = texture(40, 80, 1e6, -5e5).repeat((2, 1, 1, 1)).unwrap();
        // Depths at 1e-4 m (behind the source's near plane for most pixels) and 1e6 m, and a
        // camera pair 1e5 m from the origin.
        for offset in [0.0, 1e5] {
            let volume = census_volume(
                &images,
                &[cam(offset), cam(offset + 0.5)],
                &[1e-4, 0.5, 1e6],
                &Config::tiny(),
                4,
            )
            .unwrap();
            let v: Vec<f32> = volume.flatten_all().unwrap().to_vec1().unwrap();
            assert!(v.iter().all(|x| x.is_finite() && x.abs() <= 1.0 + 1e-5));
        }
    }
}
