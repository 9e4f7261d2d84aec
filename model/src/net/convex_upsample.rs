//! Learned convex upsampling of the depth head's 1/4 estimate to the Gaussians' resolution
//! (RAFT's upsampler, Teed and Deng 2020): each fine pixel's value is a convex combination of
//! the 3x3 coarse cells about the one it falls in, with weights a softmax the Gaussian heads'
//! features predict. Bilinear upsampling blends foreground and background across a depth
//! edge for a whole coarse cell (four image pixels); the learned weights can take each side's
//! value from its own side of the edge, since the features see the image at the finer grid.
//!
//! The softmax's logits are the bilinear weights' logarithms plus a zero-initialised
//! convolution's output, so a network trained with bilinear upsampling starts unchanged.

use candle_core::{Device, Module, Result, Tensor};
use candle_nn::VarBuilder;

use crate::ops::Conv;

/// Cells of the neighbourhood each fine pixel blends (3x3).
const TAPS: usize = 9;
/// The logit of a tap bilinear upsampling gives no weight (its softmax weight is e^-30
/// of the others': none, in f32, beside any other).
const NO_WEIGHT_LOGIT: f32 = -30.0;

/// The upsampler: a zero-initialised 3x3 convolution from the heads' features to the nine
/// taps' logit corrections.
#[derive(Clone, Debug)]
pub struct ConvexUpsample {
    mask: Conv,
}

impl ConvexUpsample {
    /// Reads `channels` channels of per-fine-pixel features.
    pub fn new(vb: VarBuilder, channels: usize) -> Result<Self> {
        Ok(Self {
            mask: Conv::zeros(vb.pp("zero_mask"), (channels, TAPS), 3, 1, 1)?,
        })
    }

    /// `coarse` `(V, 1, h, w)` to `(V, 1, hg, wg)`, the grid of `guide` `(V, c, hg, wg)`:
    /// with the convolution at zero, exactly [`crate::ops::upsample_bilinear`] (the
    /// half-pixel convention, edges clamped).
    pub fn forward(&self, coarse: &Tensor, guide: &Tensor) -> Result<Tensor> {
        let (_, _, h, w) = coarse.dims4()?;
        let (_, _, hg, wg) = guide.dims4()?;
        let device = coarse.device();
        let (rows, row_logits) = axis_taps(h, hg);
        let (cols, col_logits) = axis_taps(w, wg);
        let mut neighbours = Vec::with_capacity(TAPS);
        let mut prior = Vec::with_capacity(TAPS * hg * wg);
        for dy in 0..3 {
            let r = index(&rows, dy, h, device)?;
            for dx in 0..3 {
                let c = index(&cols, dx, w, device)?;
                neighbours.push(coarse.index_select(&r, 2)?.index_select(&c, 3)?);
                for i in 0..hg {
                    prior.extend((0..wg).map(|j| row_logits[i][dy] + col_logits[j][dx]));
                }
            }
        }
        let neighbours = Tensor::cat(&neighbours, 1)?;
        let prior = Tensor::from_vec(prior, (1, TAPS, hg, wg), device)?.to_dtype(coarse.dtype())?;
        let logits = self.mask.forward(guide)?.broadcast_add(&prior)?;
        let weights = candle_nn::ops::softmax(&logits, 1)?;
        (weights * neighbours)?.sum_keepdim(1)
    }
}

/// For each of `to` fine pixels along an axis of `from` coarse cells: the cell nearest its
/// source point (the centre of its 3-tap neighbourhood) and the logarithms of the bilinear
/// weights of the cells one before, at and one after it.
fn axis_taps(from: usize, to: usize) -> (Vec<usize>, Vec<[f32; 3]>) {
    let last = from.saturating_sub(1);
    (0..to)
        .map(|i| {
            let x = ((i as f64 + 0.5) * from as f64 / to as f64 - 0.5).clamp(0.0, last as f64);
            let centre = (x.round() as usize).min(last);
            let low = (x.floor() as usize).min(last);
            let t = x - low as f64;
            let mut weights = [0.0f64; 3];
            // `low` is the centre or the cell before it; `low + 1` the centre or the one after.
            weights[low + 1 - centre] += 1.0 - t;
            if low < last {
                weights[low + 2 - centre] += t;
            }
            let logits = weights.map(|w| match w > 0.0 {
                true => w.ln() as f32,
                false => NO_WEIGHT_LOGIT,
            });
            (centre, logits)
        })
        .unzip()
}

/// The cells `centre + offset - 1` of each fine pixel, clamped into `0..n` (the edge cell
/// repeats, as bilinear upsampling clamps).
fn index(centres: &[usize], offset: usize, n: usize, device: &Device) -> Result<Tensor> {
    let cells: Vec<u32> = centres
        .iter()
        .map(|&c| (c + offset).saturating_sub(1).min(n - 1) as u32)
        .collect();
    Tensor::from_vec(cells, centres.len(), device)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ops::upsample_bilinear;
    use candle_core::{DType, Var};
    use candle_nn::VarMap;

    fn upsampler(varmap: &VarMap, channels: usize) -> ConvexUpsample {
        let vb = VarBuilder::from_varmap(varmap, DType::F32, &Device::Cpu);
        ConvexUpsample::new(vb, channels).unwrap()
    }

    fn max_abs(t: &Tensor) -> f32 {
        t.abs().unwrap().max_all().unwrap().to_scalar().unwrap()
    }

    #[test]
    fn it_starts_as_bilinear_upsampling_at_every_ratio() {
        let up = upsampler(&VarMap::new(), 4);
        for (h, w, hg, wg) in [
            (5, 7, 10, 14),
            (5, 7, 9, 13),
            (4, 6, 16, 24),
            (3, 3, 3, 3),
            (1, 2, 2, 4),
        ] {
            let coarse = Tensor::rand(0f32, 1.0, (2, 1, h, w), &Device::Cpu).unwrap();
            let guide = Tensor::randn(0f32, 1.0, (2, 4, hg, wg), &Device::Cpu).unwrap();
            let convex = up.forward(&coarse, &guide).unwrap();
            let bilinear = upsample_bilinear(&coarse, hg, wg).unwrap();
            let diff = max_abs(&(convex - bilinear).unwrap());
            assert!(diff < 1e-5, "{h}x{w} to {hg}x{wg}: {diff}");
        }
    }

    #[test]
    fn learned_weights_keep_an_edge_that_bilinear_blurs() {
        // A step between coarse columns 1 and 2; the mask's bias pulls every fine pixel to
        // the centre tap, which is nearest-cell upsampling: no blended value anywhere.
        let varmap = VarMap::new();
        let up = upsampler(&varmap, 1);
        for (name, var) in varmap.data().lock().unwrap().iter() {
            if name.ends_with("bias") {
                let mut bias = vec![0f32; TAPS];
                bias[4] = 60.0;
                var.set(&Tensor::from_vec(bias, TAPS, &Device::Cpu).unwrap())
                    .unwrap();
            }
        }
        let step: Vec<f32> = (0..4 * 4)
            .map(|k| if k % 4 < 2 { 0.0 } else { 1.0 })
            .collect();
        let coarse = Tensor::from_vec(step, (1, 1, 4, 4), &Device::Cpu).unwrap();
        let guide = Tensor::zeros((1, 1, 8, 8), DType::F32, &Device::Cpu).unwrap();
        let fine: Vec<f32> = up
            .forward(&coarse, &guide)
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap();
        assert!(fine.iter().all(|&v| v < 1e-6 || v > 1.0 - 1e-6), "{fine:?}");
        let bilinear: Vec<f32> = upsample_bilinear(&coarse, 8, 8)
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap();
        assert!(bilinear.iter().any(|&v| v > 0.2 && v < 0.8));
    }

    #[test]
    fn it_stays_a_convex_combination_at_the_extremes() {
        let varmap = VarMap::new();
        let up = upsampler(&varmap, 3);
        for (name, var) in varmap.data().lock().unwrap().iter() {
            if name.ends_with("weight") {
                let huge =
                    (Tensor::randn(0f32, 1.0, var.shape(), &Device::Cpu).unwrap() * 1e4).unwrap();
                var.set(&huge).unwrap();
            }
        }
        for (low, high, guide_scale) in [(0f32, 1f32, 1e6), (1e-6, 2e-6, 0.0), (0.999, 1.0, 1e-6)] {
            let coarse =
                Var::from_tensor(&Tensor::rand(low, high, (2, 1, 6, 5), &Device::Cpu).unwrap())
                    .unwrap();
            let guide = Var::from_tensor(
                &(Tensor::randn(0f32, 1.0, (2, 3, 12, 10), &Device::Cpu).unwrap() * guide_scale)
                    .unwrap(),
            )
            .unwrap();
            let fine = up.forward(coarse.as_tensor(), guide.as_tensor()).unwrap();
            let v: Vec<f32> = fine.flatten_all().unwrap().to_vec1().unwrap();
            assert!(
                v.iter()
                    .all(|x| x.is_finite() && *x >= low - 1e-6 && *x <= high + 1e-6),
                "{low}..{high}"
            );
            let grads = fine.sum_all().unwrap().backward().unwrap();
            for var in [&coarse, &guide] {
                let g = grads.get(var).unwrap();
                assert!(g
                    .flatten_all()
                    .unwrap()
                    .to_vec1::<f32>()
                    .unwrap()
                    .iter()
                    .all(|x| x.is_finite()));
            }
        }
    }
}
