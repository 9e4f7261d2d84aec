//! Pseudo-view mixed training (StereoSplat+, paper section 3.3): with probability `p`
//! (the preset's `pseudo_mix`), each sampled input pair after the first is replaced by a
//! pseudo pair rendered, at that pair's own cameras, from what the current network predicts
//! from the first pair alone (G_base, no gradient), so the network learns to take the
//! progressive pass's rendered views as input. The targets, and the LiDAR depth that
//! supervises the replaced views' estimated depth, stay the true ones. The renders are raw
//! (no enhancer in the loop: the pass's `enhancer=false` row trains exactly so; with the
//! enhancer the pass sees sharper inputs than training showed it).

use candle_core::{Result, Tensor};
use rand::Rng;
use renderer::{cpu, RenderSettings};

use super::data::{image_tensor, Sample};
use crate::frame::RgbImage;
use crate::net::{to_set, StereoSplat};

/// Replaces each input pair after the first of `sample` with probability `p` by a pseudo
/// pair rendered from `net`'s prediction of the first pair; returns how many pairs it
/// replaced. Draws one number per pair after the first from `rng` (none when `p` is 0 or
/// there is one pair, so runs without mixing draw exactly as before).
pub fn mix_pseudo_pairs(
    net: &StereoSplat,
    sample: &mut Sample,
    p: f32,
    rng: &mut impl Rng,
) -> Result<usize> {
    let pairs = sample.cameras.len() / 2;
    if p <= 0.0 || pairs < 2 {
        return Ok(0);
    }
    let replaced: Vec<usize> = (1..pairs)
        .filter(|_| rng.random_bool(f64::from(p.min(1.0))))
        .collect();
    if replaced.is_empty() {
        return Ok(0);
    }
    let cfg = net.config();
    let base = net
        .forward(&sample.images.narrow(0, 0, 2)?, &sample.cameras[..2])?
        .output()?;
    // Read out as plain numbers: nothing of G_base is differentiated.
    let set = to_set(&base, None, cfg.opacity_floor, cfg.max_gaussians)?;
    let splats = set
        .view()
        .map_err(|e| candle_core::Error::Msg(format!("pseudo mix: {e}")))?;
    let settings = RenderSettings::default();
    let device = sample.images.device().clone();
    let mut views: Vec<Tensor> = (0..2 * pairs)
        .map(|v| sample.images.get(v))
        .collect::<Result<_>>()?;
    for &k in &replaced {
        for v in [2 * k, 2 * k + 1] {
            let out = cpu::render(&splats, &sample.cameras[v].params::<f32>(), &settings).output;
            let image = RgbImage {
                width: out.width,
                height: out.height,
                data: out
                    .rgb
                    .iter()
                    .map(|c| {
                        if c.is_finite() {
                            c.clamp(0.0, 1.0)
                        } else {
                            0.0
                        }
                    })
                    .collect(),
            };
            views[v] = image_tensor(&image, &device)?;
        }
    }
    sample.images = Tensor::stack(&views, 0)?;
    Ok(replaced.len())
}
