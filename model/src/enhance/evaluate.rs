//! `eval-enhancer`: scores of the raw render and of the enhanced render against the true
//! image on held-out pairs (pairs from drives training never saw): PSNR over the whole image
//! (`10 log10(1 / MSE)`, as `metrics::psnr`), PSNR on the unseen region (pixels the
//! Gaussians left nearly empty, alpha below [`UNSEEN_ALPHA`]: what the enhancer must fill in)
//! and LPIPS, each averaged over pairs.

use candle_core::{Device, Tensor};
use serde::Serialize;

use super::pairs::PairSet;
use super::{EnhanceError, Enhancer};
use crate::lpips::Lpips;

/// Pixels whose render alpha is below this count as unseen.
pub const UNSEEN_ALPHA: f32 = 0.5;

/// Mean scores of one kind of image (raw or enhanced) over the pairs.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Scores {
    /// Mean PSNR over pairs, dB.
    pub psnr: f64,
    /// Mean PSNR over the unseen pixels of the pairs that have at least one, dB.
    pub psnr_unseen: f64,
    /// Mean LPIPS over pairs.
    pub lpips: f64,
}

/// What `eval-enhancer` writes.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Pairs scored.
    pub pairs: usize,
    /// Pairs with unseen pixels (those the unseen PSNR averages).
    pub pairs_with_unseen: usize,
    /// Fraction of all pixels that are unseen.
    pub unseen_fraction: f64,
    /// The render as StereoSplat drew it.
    pub raw: Scores,
    /// The render after the enhancer.
    pub enhanced: Scores,
    /// Enhanced minus raw PSNR, dB (positive: better).
    pub psnr_gain: f64,
    /// Raw minus enhanced LPIPS (positive: better).
    pub lpips_gain: f64,
    /// Enhanced minus raw unseen-region PSNR, dB.
    pub psnr_unseen_gain: f64,
}

/// PSNR of `a` against `b` over the pixels where `mask` `(1, H, W)` is 1 (all if `None`);
/// `None` when the mask is empty.
fn psnr(a: &Tensor, b: &Tensor, mask: Option<&Tensor>) -> candle_core::Result<Option<f64>> {
    let sq = (a - b)?.sqr()?;
    let (sum, count) = match mask {
        Some(m) => (
            sq.broadcast_mul(m)?.sum_all()?.to_scalar::<f32>()? as f64,
            3.0 * m.sum_all()?.to_scalar::<f32>()? as f64,
        ),
        None => (
            sq.sum_all()?.to_scalar::<f32>()? as f64,
            sq.elem_count() as f64,
        ),
    };
    Ok((count > 0.0).then(|| 10.0 * (count / sum.max(1e-12)).log10()))
}

/// Scores `enhancer` on every pair of `set` (in batches of `batch`); `progress` gets
/// (pairs done, pairs in all).
pub fn evaluate(
    enhancer: &Enhancer,
    set: &PairSet,
    lpips: &Lpips,
    batch: usize,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Report, EnhanceError> {
    let n = set.len();
    let (mut raw, mut enh) = (Scores::default(), Scores::default());
    let (mut with_unseen, mut unseen_pixels, mut pixels) = (0usize, 0f64, 0f64);
    let indices: Vec<usize> = (0..n).collect();
    for chunk in indices.chunks(batch.max(1)) {
        let b = set.batch(chunk, false, &Device::Cpu)?;
        let rendered = b.render.narrow(1, 0, 3)?;
        let enhanced = enhancer.forward(&b.render, &b.reference)?;
        let lp_raw = lpips.forward(&rendered, &b.target)?.to_vec1::<f32>()?;
        let lp_enh = lpips.forward(&enhanced, &b.target)?.to_vec1::<f32>()?;
        let unseen = b
            .render
            .narrow(1, 3, 1)?
            .lt(UNSEEN_ALPHA)?
            .to_dtype(candle_core::DType::F32)?;
        for i in 0..chunk.len() {
            let (r, e, t, m) = (
                rendered.get(i)?,
                enhanced.get(i)?,
                b.target.get(i)?,
                unseen.get(i)?,
            );
            raw.psnr += psnr(&r, &t, None)?.unwrap_or(0.0);
            enh.psnr += psnr(&e, &t, None)?.unwrap_or(0.0);
            raw.lpips += lp_raw[i] as f64;
            enh.lpips += lp_enh[i] as f64;
            pixels += m.elem_count() as f64;
            unseen_pixels += m.sum_all()?.to_scalar::<f32>()? as f64;
            if let (Some(pr), Some(pe)) = (psnr(&r, &t, Some(&m))?, psnr(&e, &t, Some(&m))?) {
                raw.psnr_unseen += pr;
                enh.psnr_unseen += pe;
                with_unseen += 1;
            }
        }
        progress(chunk.last().map_or(0, |&i| i + 1), n);
    }
    for s in [&mut raw, &mut enh] {
        s.psnr /= n.max(1) as f64;
        s.lpips /= n.max(1) as f64;
        s.psnr_unseen /= with_unseen.max(1) as f64;
    }
    Ok(Report {
        pairs: n,
        pairs_with_unseen: with_unseen,
        unseen_fraction: unseen_pixels / pixels.max(1.0),
        psnr_gain: enh.psnr - raw.psnr,
        lpips_gain: raw.lpips - enh.lpips,
        psnr_unseen_gain: enh.psnr_unseen - raw.psnr_unseen,
        raw,
        enhanced: enh,
    })
}
