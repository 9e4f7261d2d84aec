//! The backward pass: gradients of a scalar loss, given its gradients with respect to the
//! rendered images, with respect to every Gaussian's raw parameters.
//!
//! Each pixel walks its blended Gaussians back to front (3DGS's scheme: transmittance is
//! recovered by dividing by `1 - alpha`), producing screen-space gradients per tile-list
//! entry; those are summed per Gaussian and carried through the projection.
//! Normalised depth is `depth_raw / alpha`, so its gradient is split between the two.

use rayon::prelude::*;

use super::composite::{ForwardPass, TileSplats};
use super::project::{project_backward, ProjectedGrads};
use crate::camera::CameraParams;
use crate::gaussians::SplatsView;
use crate::output::{RenderSettings, MIN_DEPTH_ALPHA};
use crate::real::Real;

/// Gradients of the loss with respect to the rendered images (`None` = the loss ignores that
/// image). Same layouts as [`crate::RenderOutput`].
#[derive(Clone, Copy, Debug, Default)]
pub struct OutputGrads<'a, T> {
    /// d loss / d rgb, interleaved.
    pub rgb: Option<&'a [T]>,
    /// d loss / d alpha-normalised depth.
    pub depth: Option<&'a [T]>,
    /// d loss / d raw expected depth.
    pub depth_raw: Option<&'a [T]>,
    /// d loss / d alpha.
    pub alpha: Option<&'a [T]>,
    /// d loss / d composited confidence.
    pub confidence: Option<&'a [T]>,
}

/// Gradients with respect to every Gaussian's raw parameters, arrays parallel to the set's.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SplatGrads<T> {
    /// d loss / d mean.
    pub means: Vec<[T; 3]>,
    /// d loss / d log scale.
    pub log_scales: Vec<[T; 3]>,
    /// d loss / d raw quaternion (x, y, z, w), before normalisation.
    pub rotations: Vec<[T; 4]>,
    /// d loss / d opacity logit (opacity = sigmoid(logit)).
    pub opacity_logits: Vec<T>,
    /// d loss / d colour.
    pub colors: Vec<[T; 3]>,
    /// d loss / d confidence.
    pub confidences: Vec<T>,
}

/// Screen-space gradients of one tile-list entry.
#[derive(Clone, Copy, Default)]
struct EntryGrads<T> {
    screen: ProjectedGrads<T>,
    color: [T; 3],
    confidence: T,
}

/// The loss gradients at one pixel, with normalised depth folded into raw depth and alpha.
struct PixelGrads<T> {
    rgb: [T; 3],
    depth_raw: T,
    alpha: T,
    confidence: T,
}

fn pixel_grads<T: Real>(g: &OutputGrads<'_, T>, fwd: &ForwardPass<T>, i: usize) -> PixelGrads<T> {
    let at = |s: Option<&[T]>, k: usize| s.map_or(T::zero(), |s| s[k]);
    let mut p = PixelGrads {
        rgb: [0, 1, 2].map(|k| at(g.rgb, 3 * i + k)),
        depth_raw: at(g.depth_raw, i),
        alpha: at(g.alpha, i),
        confidence: at(g.confidence, i),
    };
    let alpha = fwd.output.alpha[i];
    let gd = at(g.depth, i);
    if alpha > T::c(MIN_DEPTH_ALPHA) {
        p.depth_raw = p.depth_raw + gd / alpha;
        p.alpha = p.alpha - gd * fwd.output.depth_raw[i] / (alpha * alpha);
    }
    p
}

/// Gradients of the loss with respect to the parameters of `splats`, given the forward pass
/// that rendered them with the same camera and settings.
pub fn backward<T: Real>(
    splats: &SplatsView<'_, T>,
    cam: &CameraParams<T>,
    settings: &RenderSettings,
    fwd: &ForwardPass<T>,
    grads: &OutputGrads<'_, T>,
) -> SplatGrads<T> {
    let bins = &fwd.bins;
    let (w, h) = (cam.width, cam.height);
    let bg = settings.background.map(|v| T::c(v as f64));
    let per_tile: Vec<Vec<EntryGrads<T>>> = (0..bins.tile_count())
        .into_par_iter()
        .map(|t| {
            let splats = TileSplats::new(bins, &fwd.projected, t);
            let mut acc = vec![EntryGrads::default(); splats.list.len()];
            for ([x0, x1, y0, y1], cands) in splats.blocks(t, bins.grid[0], w, h) {
                for (x, y) in (y0..=y1).flat_map(|y| (x0..=x1).map(move |x| (x, y))) {
                    let i = (y * w + x) as usize;
                    let g = pixel_grads(grads, fwd, i);
                    let (px, py) = (T::c(x as f64), T::c(y as f64));
                    let t_final = fwd.final_t[i];
                    let mut t_cur = t_final;
                    let mut rec = [T::zero(); 5]; // rgb, depth, confidence behind the current one
                    let mut last = [T::zero(); 5];
                    let mut last_alpha = T::zero();
                    let bg_dot = (0..3).fold(T::zero(), |s, k| s + bg[k] * g.rgb[k]);
                    let gv = [g.rgb[0], g.rgb[1], g.rgb[2], g.depth_raw, g.confidence];
                    for &pos in cands
                        .iter()
                        .rev()
                        .skip_while(|&&pos| pos >= fwd.n_contrib[i])
                    {
                        let Some((alpha, gauss, clamped)) = splats.alpha_at(pos, px, py) else {
                            continue;
                        };
                        let p = &splats.list[pos as usize];
                        let pos = pos as usize;
                        t_cur = t_cur / (T::one() - alpha);
                        let wgt = alpha * t_cur;
                        let vals = [p.color[0], p.color[1], p.color[2], p.depth, p.confidence];
                        let mut d_alpha = T::zero();
                        for k in 0..5 {
                            rec[k] = last_alpha * last[k] + (T::one() - last_alpha) * rec[k];
                            d_alpha = d_alpha + (vals[k] - rec[k]) * gv[k];
                        }
                        last = vals;
                        last_alpha = alpha;
                        d_alpha = d_alpha * t_cur;
                        let through = t_final / (T::one() - alpha);
                        d_alpha = d_alpha - through * bg_dot + through * g.alpha;

                        let e = &mut acc[pos];
                        for k in 0..3 {
                            e.color[k] = e.color[k] + wgt * g.rgb[k];
                        }
                        e.confidence = e.confidence + wgt * g.confidence;
                        e.screen.depth = e.screen.depth + wgt * g.depth_raw;
                        if clamped {
                            continue;
                        }
                        e.screen.opacity = e.screen.opacity + gauss * d_alpha;
                        let d_power = p.opacity * gauss * d_alpha;
                        let dx = p.mean2d[0] - px;
                        let dy = p.mean2d[1] - py;
                        let [a, b, c] = p.conic;
                        e.screen.mean2d[0] = e.screen.mean2d[0] - d_power * (a * dx + b * dy);
                        e.screen.mean2d[1] = e.screen.mean2d[1] - d_power * (b * dx + c * dy);
                        e.screen.conic[0] = e.screen.conic[0] - T::c(0.5) * dx * dx * d_power;
                        e.screen.conic[1] = e.screen.conic[1] - dx * dy * d_power;
                        e.screen.conic[2] = e.screen.conic[2] - T::c(0.5) * dy * dy * d_power;
                    }
                }
            }
            acc
        })
        .collect();

    let n = splats.len();
    let mut screen = vec![ProjectedGrads::default(); n];
    let mut out = SplatGrads {
        colors: vec![[T::zero(); 3]; n],
        confidences: vec![T::zero(); n],
        ..Default::default()
    };
    for (t, acc) in per_tile.iter().enumerate() {
        for (&id, e) in bins.tile(t).iter().zip(acc) {
            let id = id as usize;
            let s = &mut screen[id];
            for k in 0..2 {
                s.mean2d[k] = s.mean2d[k] + e.screen.mean2d[k];
            }
            for k in 0..3 {
                s.conic[k] = s.conic[k] + e.screen.conic[k];
                out.colors[id][k] = out.colors[id][k] + e.color[k];
            }
            s.depth = s.depth + e.screen.depth;
            s.opacity = s.opacity + e.screen.opacity;
            out.confidences[id] = out.confidences[id] + e.confidence;
        }
    }
    let params: Vec<_> = (0..n)
        .into_par_iter()
        .map(|i| match fwd.projected[i] {
            Some(_) => project_backward(splats, i, cam, &screen[i]),
            None => Default::default(),
        })
        .collect();
    out.means = params.iter().map(|p| p.mean).collect();
    out.log_scales = params.iter().map(|p| p.log_scale).collect();
    out.rotations = params.iter().map(|p| p.rotation).collect();
    out.opacity_logits = params.iter().map(|p| p.opacity_logit).collect();
    out
}
