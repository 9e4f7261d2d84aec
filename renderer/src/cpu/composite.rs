//! Compositing and the whole forward pass: project, bin, then blend each pixel front to back.
//!
//! Per pixel: `alpha = min(MAX_ALPHA, opacity * exp(power))`, skipped below [`MIN_ALPHA`];
//! compositing stops before the Gaussian that would take transmittance below
//! [`MIN_TRANSMITTANCE`]; the background fills what remains.

use rayon::prelude::*;

use super::project::{project, Projected};
use super::tiles::{bin, TileBins};
use super::TILE_SIZE;
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

/// The Gaussian's exponent at pixel centre `(px, py)`: `-0.5 d^T Q d` with `d = mean2d - p`.
/// Every path (per pixel, per block, backward) computes it with this one expression, so they
/// agree to the bit.
#[inline(always)]
fn power_at<T: Real>(p: &Projected<T>, px: T, py: T) -> T {
    let dx = p.mean2d[0] - px;
    let dy = p.mean2d[1] - py;
    T::c(-0.5) * (p.conic[0] * dx * dx + p.conic[2] * dy * dy) - p.conic[1] * dx * dy
}

/// The blend of a Gaussian given its exponent at a pixel, or `None` when it is skipped there.
/// Returns (alpha, exp(power), whether alpha hit the [`MAX_ALPHA`] clamp).
#[inline]
fn alpha_from_power<T: Real>(p: &Projected<T>, power: T) -> Option<(T, T, bool)> {
    if power > T::zero() {
        return None;
    }
    let g = power.exp();
    let raw = p.opacity * g;
    let alpha = raw.min(T::c(MAX_ALPHA));
    (alpha >= T::c(MIN_ALPHA)).then_some((alpha, g, raw >= T::c(MAX_ALPHA)))
}

/// A tile's composited pixels with their image coordinates.
type TileResults<T> = Vec<((u32, u32), PixelResult<T>)>;

/// One pixel's composited values.
#[derive(Clone, Copy, Default)]
struct PixelResult<T> {
    rgb: [T; 3],
    depth_raw: T,
    confidence: T,
    final_t: T,
    n_contrib: u32,
    surface_depth: T,
    half_depth: T,
}

/// Edge of the square pixel blocks a tile is split into for candidate culling.
const BLOCK: u32 = 4;

/// A tile's Gaussians in list order, with the pixel box outside of which each one's alpha is
/// below [`MIN_ALPHA`] (from `d^T Q d <= 2 ln(255 o)`, widened slightly for rounding). Blocks
/// of [`BLOCK`]x[`BLOCK`] pixels composite only the Gaussians whose box they meet; since
/// every Gaussian left out would have been skipped at every pixel of the block anyway, the
/// result is exactly that of walking the whole list, which the wgpu rasterizer does.
pub(crate) struct TileSplats<T> {
    /// The tile's Gaussians, front to back.
    pub list: Vec<Projected<T>>,
    boxes: Vec<[T; 4]>,
    /// Per Gaussian, an exponent below which its alpha is surely under [`MIN_ALPHA`]:
    /// `ln(MIN_ALPHA / opacity)` less a margin far above `exp`'s rounding, so the test only
    /// saves the `exp` and never changes a result.
    min_power: Vec<T>,
}

impl<T: Real> TileSplats<T> {
    /// Gathers tile `t`'s Gaussians (tile lists hold only Gaussians that were not culled).
    pub fn new(bins: &TileBins, projected: &[Option<Projected<T>>], t: usize) -> Self {
        let list: Vec<Projected<T>> = bins
            .tile(t)
            .iter()
            .filter_map(|&i| projected[i as usize])
            .collect();
        let boxes = list.iter().map(alpha_box).collect();
        let min_power = list
            .iter()
            .map(|p| (T::c(MIN_ALPHA) / p.opacity).ln() - T::c(1e-3))
            .collect();
        Self {
            list,
            boxes,
            min_power,
        }
    }

    /// The blend of the Gaussian at `pos` at pixel `(px, py)` (`None` where it is skipped),
    /// skipping the `exp` where it cannot matter.
    #[inline]
    pub fn alpha_at(&self, pos: u32, px: T, py: T) -> Option<(T, T, bool)> {
        let p = &self.list[pos as usize];
        let power = power_at(p, px, py);
        if power < self.min_power[pos as usize] {
            return None;
        }
        alpha_from_power(p, power)
    }

    /// The blocks of tile `t` inside the image, each with the positions (in list order) of
    /// the Gaussians whose box meets it.
    pub fn blocks(
        &self,
        t: usize,
        grid_x: u32,
        width: u32,
        height: u32,
    ) -> Vec<([u32; 4], Vec<u32>)> {
        let tx = t as u32 % grid_x * TILE_SIZE;
        let ty = t as u32 / grid_x * TILE_SIZE;
        let nx = ((tx + TILE_SIZE).min(width) - tx).div_ceil(BLOCK);
        let ny = ((ty + TILE_SIZE).min(height) - ty).div_ceil(BLOCK);
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); (nx * ny) as usize];
        // Block index range a box covers, clamped to the tile.
        let span = |lo: T, hi: T, origin: u32, n: u32| {
            let b = T::c(BLOCK as f64);
            let first = ((lo - T::c(origin as f64)) / b).floor().max(T::zero());
            let last = ((hi - T::c(origin as f64)) / b)
                .floor()
                .min(T::c(n as f64 - 1.0));
            (first <= last).then(|| (first.to_u32().unwrap_or(0), last.to_u32().unwrap_or(0)))
        };
        for (pos, bx) in self.boxes.iter().enumerate() {
            let (Some((x0, x1)), Some((y0, y1))) =
                (span(bx[0], bx[1], tx, nx), span(bx[2], bx[3], ty, ny))
            else {
                continue;
            };
            for by in y0..=y1 {
                for bxi in x0..=x1 {
                    lists[(by * nx + bxi) as usize].push(pos as u32);
                }
            }
        }
        lists
            .into_iter()
            .enumerate()
            .map(|(k, list)| {
                let x0 = tx + (k as u32 % nx) * BLOCK;
                let y0 = ty + (k as u32 / nx) * BLOCK;
                (
                    [
                        x0,
                        (x0 + BLOCK).min(width) - 1,
                        y0,
                        (y0 + BLOCK).min(height) - 1,
                    ],
                    list,
                )
            })
            .collect()
    }
}

/// The pixel box (x min, x max, y min, y max) beyond which a Gaussian's alpha is below
/// [`MIN_ALPHA`]; empty (min > max) when its opacity is too low to ever reach it.
fn alpha_box<T: Real>(p: &Projected<T>) -> [T; 4] {
    let level = T::c(2.0) * (p.opacity / T::c(MIN_ALPHA)).ln();
    let [a, b, c] = p.conic;
    let det = a * c - b * b;
    if level.is_nan() || level <= T::zero() || det.is_nan() || det <= T::zero() {
        return [T::one(), T::zero(), T::one(), T::zero()];
    }
    // Extent of {d : d^T Q d <= level} is sqrt(level * (Q^-1)_ii); widened for rounding.
    let widen = T::c(1.001);
    let hx = (level * widen * c / det).sqrt() + T::c(0.01);
    let hy = (level * widen * a / det).sqrt() + T::c(0.01);
    [
        p.mean2d[0] - hx,
        p.mean2d[0] + hx,
        p.mean2d[1] - hy,
        p.mean2d[1] + hy,
    ]
}

/// Composites the pixels of one block, `[x0, x1] x [y0, y1]` (at most [`BLOCK`]^2 of them),
/// over the block's candidates in list order. Each candidate's exponent is computed for all
/// pixels at once (straight-line code the compiler vectorizes); only pixels above the
/// candidate's `min_power` go on to the per-pixel rules, which are exactly those of a pixel
/// walking the whole list: skip, blend, or stop before transmittance drops under
/// [`MIN_TRANSMITTANCE`].
///
/// `level` is the transmittance at which a pixel's surface depth is taken
/// (`1 - RenderSettings::surface_opacity`).
fn composite_block<T: Real>(
    splats: &TileSplats<T>,
    candidates: &[u32],
    rect: [u32; 4],
    level: T,
) -> TileResults<T> {
    const N: usize = (BLOCK * BLOCK) as usize;
    let [x0, x1, y0, y1] = rect;
    let bw = x1 - x0 + 1;
    let count = (bw * (y1 - y0 + 1)) as usize;
    let mut px = [T::zero(); N];
    let mut py = [T::zero(); N];
    for j in 0..N {
        // Lanes past the block's edge repeat its first pixel and are never live.
        let k = if j < count { j as u32 } else { 0 };
        px[j] = T::c((x0 + k % bw) as f64);
        py[j] = T::c((y0 + k / bw) as f64);
    }
    let mut res = [PixelResult {
        final_t: T::one(),
        ..Default::default()
    }; N];
    let mut live: u32 = if count == N {
        u32::MAX >> (32 - N)
    } else {
        (1 << count) - 1
    };
    let mut power = [T::zero(); N];
    for &pos in candidates {
        if live == 0 {
            break;
        }
        let p = &splats.list[pos as usize];
        let floor = splats.min_power[pos as usize];
        let mut hit = 0u32;
        for j in 0..N {
            power[j] = power_at(p, px[j], py[j]);
            hit |= u32::from(power[j] >= floor) << j;
        }
        hit &= live;
        while hit != 0 {
            let j = hit.trailing_zeros() as usize;
            hit &= hit - 1;
            let Some((alpha, _, _)) = alpha_from_power(p, power[j]) else {
                continue;
            };
            let r = &mut res[j];
            let next_t = r.final_t * (T::one() - alpha);
            if next_t < T::c(MIN_TRANSMITTANCE) {
                live &= !(1 << j);
                continue;
            }
            if r.final_t > T::c(0.5) && next_t <= T::c(0.5) {
                r.half_depth = p.depth;
            }
            if r.final_t > level && next_t <= level {
                r.surface_depth = p.depth;
            }
            let w = alpha * r.final_t;
            for k in 0..3 {
                r.rgb[k] = r.rgb[k] + w * p.color[k];
            }
            r.depth_raw = r.depth_raw + w * p.depth;
            r.confidence = r.confidence + w * p.confidence;
            r.final_t = next_t;
            r.n_contrib = pos + 1;
        }
    }
    (0..count)
        .map(|j| ((x0 + j as u32 % bw, y0 + j as u32 / bw), res[j]))
        .collect()
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
    let level = T::one() - T::c(settings.surface_opacity as f64);
    let per_tile: Vec<TileResults<T>> = (0..bins.tile_count())
        .into_par_iter()
        .map(|t| {
            let splats = TileSplats::new(&bins, &projected, t);
            let mut results = Vec::with_capacity((TILE_SIZE * TILE_SIZE) as usize);
            for (rect, cands) in splats.blocks(t, bins.grid[0], w, h) {
                results.extend(composite_block(&splats, &cands, rect, level));
            }
            results
        })
        .collect();

    let bg = settings.background.map(|v| T::c(v as f64));
    let mut out = RenderOutput::zeros(w, h);
    let n = out.pixels();
    let mut final_t = vec![T::one(); n];
    let mut n_contrib = vec![0u32; n];
    for results in &per_tile {
        for &((x, y), r) in results {
            let i = (y * w + x) as usize;
            let alpha = T::one() - r.final_t;
            for (o, (c, b)) in out.rgb[3 * i..3 * i + 3]
                .iter_mut()
                .zip(r.rgb.iter().zip(&bg))
            {
                *o = *c + r.final_t * *b;
            }
            out.depth_raw[i] = r.depth_raw;
            out.depth[i] = if alpha > T::c(MIN_DEPTH_ALPHA) {
                r.depth_raw / alpha
            } else {
                T::zero()
            };
            out.alpha[i] = alpha;
            out.confidence[i] = r.confidence;
            out.surface_depth[i] = match r.surface_depth > T::zero() {
                true => r.surface_depth,
                false => r.half_depth,
            };
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
