//! Semi-global aggregation (Hirschmüller 2008): along each path direction r the cost
//! L_r(p, d) = C(p, d) + min(L_r(p-r, d), L_r(p-r, d±1) + P1, min_k L_r(p-r, k) + P2) -
//! min_k L_r(p-r, k), summed over the directions. P2 shrinks where the grey level jumps
//! between p-r and p, so depth edges that follow image edges stay sharp.
//!
//! The image is streamed row by row, as OpenCV's `StereoSGBM` does: a path keeps only its
//! previous row (`W x D` values) and the matching costs of a row are computed when the sweep
//! reaches it. [`Paths::Five`] is one top-to-bottom sweep (left, right, up-left, up, up-right
//! neighbours), so a row's sum is final at once and memory stays `O(W x D)`.
//! [`Paths::Eight`] adds a bottom-to-top sweep over the other four directions; the first
//! sweep's sums wait for it in one `u16` volume, `2 x W x H x D` bytes.

use rayon::prelude::*;

use super::census::{cost_row, Grey, MAX_CENSUS_COST};

/// Smoothness penalties of the aggregation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Penalties {
    /// Penalty for a disparity change of one level between neighbours.
    pub p1: u16,
    /// Penalty for a larger jump, before the intensity adaptation.
    pub p2: u16,
    /// Grey-level step (0..255 scale) that halves P2: P2_eff = P2 / (1 + |dI| / this).
    pub p2_gradient: f32,
}

impl Penalties {
    /// P2 for a grey-level step `di`, never below P1 + 1 so large jumps always cost more.
    fn p2_at(&self, di: f32) -> i16 {
        let scaled = self.p2 as f32 / (1.0 + di.abs() / self.p2_gradient.max(1e-3));
        (scaled as u16).max(self.p1 + 1) as i16
    }
}

/// How many path directions are aggregated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Paths {
    /// One sweep, five directions (OpenCV's `MODE_SGBM`): memory `O(W x D)`.
    Five,
    /// Two sweeps, all eight directions (OpenCV's `MODE_HH`): a `2 x W x H x D`-byte volume.
    Eight,
}

/// Largest P2 accepted: a path cost is at most `MAX_CENSUS_COST + P2`, and eight of them
/// must stay within `i16`, the type the path costs are computed in (SSE2 has a signed
/// 16-bit minimum, not an unsigned one, so `i16` is what the compiler vectorises).
pub const MAX_P2: u16 = (i16::MAX as u16 / 8) - MAX_CENSUS_COST as u16;

/// Directions (dx, dy) of the top-to-bottom sweep.
const DOWN: [(i64, i64); 4] = [(1, 0), (1, 1), (0, 1), (-1, 1)];
/// Directions of the bottom-to-top sweep.
const UP: [(i64, i64); 4] = [(-1, 0), (-1, -1), (0, -1), (1, -1)];

/// The images a sweep reads: census strings of both views and the left grey image.
pub struct Inputs<'a> {
    /// Left census strings, row major.
    pub left: &'a [u64],
    /// Right census strings, row major.
    pub right: &'a [u64],
    /// The left grey image (its size is the pair's), for the adaptive P2.
    pub grey: &'a Grey,
    /// Disparity levels searched, `0..levels`.
    pub levels: usize,
}

/// Aggregates the costs of the pair along `paths` directions and hands each row's summed
/// costs (`[x][d]`, `W x levels` values) to `on_row` once they are final, in no fixed row
/// order.
pub fn aggregate(
    inputs: &Inputs<'_>,
    penalties: Penalties,
    paths: Paths,
    mut on_row: impl FnMut(usize, &[u16]),
) {
    let (w, h, levels) = (inputs.grey.width, inputs.grey.height, inputs.levels);
    let row_len = w * levels;
    match paths {
        Paths::Five => {
            let mut dirs = DOWN.to_vec();
            dirs.push((-1, 0));
            sweep(inputs, penalties, &dirs, |y, sum| on_row(y, sum));
        }
        Paths::Eight => {
            let mut volume = vec![0u16; row_len * h];
            sweep(inputs, penalties, &DOWN, |y, sum| {
                volume[y * row_len..(y + 1) * row_len].copy_from_slice(sum);
            });
            sweep(inputs, penalties, &UP, |y, sum| {
                let row = &mut volume[y * row_len..(y + 1) * row_len];
                row.iter_mut().zip(sum).for_each(|(v, s)| *v += *s);
                on_row(y, row);
            });
        }
    }
}

/// One sweep over the rows in the vertical order of `dirs` (all share dy's sign or are 0),
/// the directions computed in parallel; `on_row` gets each row's sum over `dirs`.
fn sweep(
    inputs: &Inputs<'_>,
    penalties: Penalties,
    dirs: &[(i64, i64)],
    mut on_row: impl FnMut(usize, &[u16]),
) {
    let (w, h, levels) = (inputs.grey.width, inputs.grey.height, inputs.levels);
    let upward = dirs.iter().any(|&(_, dy)| dy < 0);
    let mut paths: Vec<PathState> = dirs
        .iter()
        .map(|&dir| PathState::new(dir, w, levels))
        .collect();
    let mut cost = vec![0u8; w * levels];
    let mut sum = vec![0u16; w * levels];
    let mut previous: Option<usize> = None;
    for step in 0..h {
        let y = if upward { h - 1 - step } else { step };
        let codes = y * w..(y + 1) * w;
        cost_row(
            &inputs.left[codes.clone()],
            &inputs.right[codes],
            levels,
            &mut cost,
        );
        let grey = inputs.grey;
        let rows = Rows {
            current: &grey.data[y * w..(y + 1) * w],
            previous: previous.map(|py| &grey.data[py * w..(py + 1) * w]),
        };
        paths
            .par_iter_mut()
            .for_each(|p| p.row(&cost, &rows, levels, penalties));
        let chunk = levels * w.div_ceil(rayon::current_num_threads().max(1)).max(1);
        sum.par_chunks_mut(chunk).enumerate().for_each(|(i, out)| {
            let at = i * chunk;
            out.fill(0);
            for p in &paths {
                let row = &p.latest()[at..at + out.len()];
                out.iter_mut().zip(row).for_each(|(o, v)| *o += *v as u16);
            }
        });
        on_row(y, &sum);
        previous = Some(y);
    }
}

/// Grey rows of the pixel row being aggregated and of the one the sweep did before it.
struct Rows<'a> {
    /// This row.
    current: &'a [f32],
    /// The row before it in the sweep's order; `None` on the first.
    previous: Option<&'a [f32]>,
}

/// One direction's path costs over the last row or two.
struct PathState {
    /// Horizontal step of the direction: the predecessor of x is x - dx.
    dx: i64,
    /// Whether the predecessor lies on the previous row (otherwise on the same row).
    vertical: bool,
    /// Path costs of the previous row, `[x][d]`.
    prev: Vec<i16>,
    /// Their minimum over d per pixel.
    prev_min: Vec<i16>,
    /// Path costs of the current row.
    cur: Vec<i16>,
    /// Their minimum over d per pixel.
    cur_min: Vec<i16>,
    /// The predecessor's costs with a sentinel at each end, so d ± 1 need no checks.
    pred: Vec<i16>,
}

/// Stands in for the costs of the disparities beyond the searched range.
const SENTINEL: i16 = i16::MAX / 2;

impl PathState {
    fn new((dx, dy): (i64, i64), width: usize, levels: usize) -> Self {
        Self {
            dx,
            vertical: dy != 0,
            prev: vec![0; width * levels],
            prev_min: vec![0; width],
            cur: vec![0; width * levels],
            cur_min: vec![0; width],
            pred: vec![SENTINEL; levels + 2],
        }
    }

    /// The path costs of the row computed last.
    fn latest(&self) -> &[i16] {
        match self.vertical {
            true => &self.prev,
            false => &self.cur,
        }
    }

    /// Computes the path costs of a row from its matching costs `cost` (`[x][d]`). Pixels
    /// are visited in the direction's x order, so a same-row predecessor is done first.
    fn row(&mut self, cost: &[u8], rows: &Rows<'_>, levels: usize, penalties: Penalties) {
        let w = rows.current.len();
        let has_previous = rows.previous.is_some();
        for i in 0..w {
            let x = if self.dx >= 0 { i } else { w - 1 - i };
            let cell = &cost[x * levels..(x + 1) * levels];
            let px = x as i64 - self.dx;
            let in_row = (0..w as i64).contains(&px);
            let cur_row = x * levels..(x + 1) * levels;
            let best = match (self.vertical, in_row) {
                (true, true) if has_previous => {
                    let px = px as usize;
                    let grey_prev = rows.previous.map_or(0.0, |r| r[px]);
                    let jump = penalties.p2_at(rows.current[x] - grey_prev);
                    self.pred[1..=levels]
                        .copy_from_slice(&self.prev[px * levels..(px + 1) * levels]);
                    let out = &mut self.cur[cur_row];
                    step(cell, &self.pred, self.prev_min[px], jump, penalties.p1, out)
                }
                (false, true) => {
                    let px = px as usize;
                    let jump = penalties.p2_at(rows.current[x] - rows.current[px]);
                    self.pred[1..=levels]
                        .copy_from_slice(&self.cur[px * levels..(px + 1) * levels]);
                    let out = &mut self.cur[cur_row];
                    step(cell, &self.pred, self.cur_min[px], jump, penalties.p1, out)
                }
                _ => {
                    let out = &mut self.cur[cur_row];
                    out.iter_mut().zip(cell).for_each(|(o, &c)| *o = c as i16);
                    cell.iter().copied().min().map_or(0, i16::from)
                }
            };
            self.cur_min[x] = best;
        }
        if self.vertical {
            std::mem::swap(&mut self.prev, &mut self.cur);
            std::mem::swap(&mut self.prev_min, &mut self.cur_min);
        }
    }
}

/// One pixel's path costs from its matching costs `cell` and its predecessor's `pred`
/// (sentinel-padded), minimum `pm` and effective P2 `jump`; returns their minimum.
fn step(cell: &[u8], pred: &[i16], pm: i16, jump: i16, p1: u16, out: &mut [i16]) -> i16 {
    let p1 = p1 as i16;
    let jump = pm + jump;
    let n = out.len();
    // Equal-length slices, so the loop has no bounds checks and vectorises.
    let (cell, below, same, above) = (&cell[..n], &pred[..n], &pred[1..n + 1], &pred[2..n + 2]);
    let mut best = i16::MAX;
    for d in 0..n {
        let v = cell[d] as i16 + same[d].min(below[d].min(above[d]) + p1).min(jump) - pm;
        out[d] = v;
        best = best.min(v);
    }
    best
}
