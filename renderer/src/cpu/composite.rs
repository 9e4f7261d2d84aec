//! Compositing and the whole forward pass: project, bin, then blend each pixel front to back.
//!
//! Per pixel: `alpha = min(MAX_ALPHA, opacity * exp(power))`, skipped below [`MIN_ALPHA`];
//! compositing stops before the Gaussian that would take transmittance below
//! [`MIN_TRANSMITTANCE`]; the background fills what remains.

use rayon::prelude::*;

use super::project::{project, Projected};
use super::tiles::{bin, TileBins, TILE_SIZE};
use super::{MAX_ALPHA, MIN_ALPHA, MIN_TRANSMITTANCE};
use crate::camera::CameraParams;
use crate::gaussians::SplatsView;
use crate::output::{RenderOutput, RenderSettings, MIN_DEPTH_ALPHA};
use crate::real::Real;

/// Everything the forward pass computed that the backward pass needs again.
#[derive(Clone, Debug, Default)]
pub struct ForwardPass<T> {
    /// Each Gaussian's projection, `None` where culled.
    pub projected: Vec<Option<Projected<T>>>,
    /// Per-tile front-to-back lists.
    pub bins: TileBins,
    /// Final transmittance per pixel.
    pub final_t: Vec<T>,
    /// Per pixel, one past the position (in its tile's list) of the last Gaussian blended.
    pub n_contrib: Vec<u32>,
    /// The images.
    pub output: RenderOutput<T>,
}

/// The blend of one Gaussian at one pixel, or `None` when it is skipped there.
/// Returns (alpha, exp(power), whether alpha hit the [`MAX_ALPHA`] clamp).
#[inline]
pub(crate) fn pixel_alpha<T: Real>(p: &Projected<T>, px: T, py: T) -> Option<(T, T, bool)> {
    let dx = p.mean2d[0] - px;
    let dy = p.mean2d[1] - py;
    let power = T::c(-0.5) * (p.conic[0] * dx * dx + p.conic[2] * dy * dy) - p.conic[1] * dx * dy;
    if power > T::zero() {
        return None;
    }
    let g = power.exp();
    let raw = p.opacity * g;
    let alpha = raw.min(T::c(MAX_ALPHA));
    (alpha >= T::c(MIN_ALPHA)).then_some((alpha, g, raw >= T::c(MAX_ALPHA)))
}

/// One pixel's composited values.
#[derive(Clone, Copy, Default)]
struct PixelResult<T> {
    rgb: [T; 3],
    depth_raw: T,
    confidence: T,
    final_t: T,
    n_contrib: u32,
}

/// Pixel coordinates of the pixels of tile `t` that lie inside the image.
pub(crate) fn tile_pixels(
    t: usize,
    grid_x: u32,
    width: u32,
    height: u32,
) -> impl Iterator<Item = (u32, u32)> {
    let tx = t as u32 % grid_x;
    let ty = t as u32 / grid_x;
    let x0 = tx * TILE_SIZE;
    let y0 = ty * TILE_SIZE;
    (y0..(y0 + TILE_SIZE).min(height))
        .flat_map(move |y| (x0..(x0 + TILE_SIZE).min(width)).map(move |x| (x, y)))
}

fn composite_pixel<T: Real>(list: &[Projected<T>], px: T, py: T) -> PixelResult<T> {
    let mut r = PixelResult {
        final_t: T::one(),
        ..Default::default()
    };
    for (pos, p) in list.iter().enumerate() {
        let Some((alpha, _, _)) = pixel_alpha(p, px, py) else {
            continue;
        };
        let next_t = r.final_t * (T::one() - alpha);
        if next_t < T::c(MIN_TRANSMITTANCE) {
            break;
        }
        let w = alpha * r.final_t;
        for k in 0..3 {
            r.rgb[k] = r.rgb[k] + w * p.color[k];
        }
        r.depth_raw = r.depth_raw + w * p.depth;
        r.confidence = r.confidence + w * p.confidence;
        r.final_t = next_t;
        r.n_contrib = pos as u32 + 1;
    }
    r
}

/// Renders `splats` from `cam`, keeping what the backward pass needs.
pub fn render<T: Real>(
    splats: &SplatsView<'_, T>,
    cam: &CameraParams<T>,
    settings: &RenderSettings,
) -> ForwardPass<T> {
    let projected: Vec<Option<Projected<T>>> = (0..splats.len())
        .into_par_iter()
        .map(|i| project(splats, i, cam, settings))
        .collect();
    let bins = bin(&projected, cam.width, cam.height);
    let (w, h) = (cam.width, cam.height);
    let per_tile: Vec<Vec<PixelResult<T>>> = (0..bins.tile_count())
        .into_par_iter()
        .map(|t| {
            let list: Vec<Projected<T>> = bins
                .tile(t)
                .iter()
                .filter_map(|&i| projected[i as usize])
                .collect();
            tile_pixels(t, bins.grid[0], w, h)
                .map(|(x, y)| composite_pixel(&list, T::c(x as f64), T::c(y as f64)))
                .collect()
        })
        .collect();

    let bg = settings.background.map(|v| T::c(v as f64));
    let mut out = RenderOutput::zeros(w, h);
    let n = out.pixels();
    let mut final_t = vec![T::one(); n];
    let mut n_contrib = vec![0u32; n];
    for (t, results) in per_tile.iter().enumerate() {
        for ((x, y), r) in tile_pixels(t, bins.grid[0], w, h).zip(results) {
            let i = (y * w + x) as usize;
            let alpha = T::one() - r.final_t;
            for k in 0..3 {
                out.rgb[3 * i + k] = r.rgb[k] + r.final_t * bg[k];
            }
            out.depth_raw[i] = r.depth_raw;
            out.depth[i] = if alpha > T::c(MIN_DEPTH_ALPHA) {
                r.depth_raw / alpha
            } else {
                T::zero()
            };
            out.alpha[i] = alpha;
            out.confidence[i] = r.confidence;
            final_t[i] = r.final_t;
            n_contrib[i] = r.n_contrib;
        }
    }
    ForwardPass {
        projected,
        bins,
        final_t,
        n_contrib,
        output: out,
    }
}
