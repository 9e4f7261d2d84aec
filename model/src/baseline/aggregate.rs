//! Semi-global aggregation (Hirschmüller 2008): along each path direction r the cost
//! L_r(p, d) = C(p, d) + min(L_r(p-r, d), L_r(p-r, d±1) + P1, min_k L_r(p-r, k) + P2) -
//! min_k L_r(p-r, k), summed over 4 or 8 directions. P2 shrinks where the grey level jumps
//! between p-r and p, so depth edges that follow image edges stay sharp.

use rayon::prelude::*;

use super::census::Grey;

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
    fn p2_at(&self, di: f32) -> u16 {
        let scaled = self.p2 as f32 / (1.0 + di.abs() / self.p2_gradient.max(1e-3));
        (scaled as u16).max(self.p1 + 1)
    }
}

/// The four horizontal and vertical path directions (dx, dy).
const STRAIGHT: [(i64, i64); 4] = [(1, 0), (-1, 0), (0, 1), (0, -1)];
/// The four diagonal path directions (dx, dy).
const DIAGONAL: [(i64, i64); 4] = [(1, 1), (-1, 1), (1, -1), (-1, -1)];

/// Sums the path costs over 4 (`diagonals = false`) or 8 directions into a `[y][x][d]`
/// volume. Each path cost is at most `MAX_COST + P2`, so with P2 below 4000 the sum of 8
/// stays within u16. Directions run in parallel, one partial sum per worker thread.
pub fn aggregate(
    cost: &[u8],
    grey: &Grey,
    levels: usize,
    penalties: Penalties,
    diagonals: bool,
) -> Vec<u16> {
    let mut dirs = STRAIGHT.to_vec();
    if diagonals {
        dirs.extend_from_slice(&DIAGONAL);
    }
    let groups = rayon::current_num_threads().clamp(1, dirs.len());
    let per_group = dirs.len().div_ceil(groups);
    dirs.par_chunks(per_group)
        .map(|group| {
            let mut sum = vec![0u16; cost.len()];
            for &dir in group {
                accumulate_path(cost, grey, levels, penalties, dir, &mut sum);
            }
            sum
        })
        .reduce_with(|mut a, b| {
            a.iter_mut().zip(&b).for_each(|(x, y)| *x += *y);
            a
        })
        .unwrap_or_else(|| vec![0u16; cost.len()])
}

/// Adds the path cost of direction `(dx, dy)` to `sum`. Rows are visited in the direction's
/// y order and pixels in its x order, so each predecessor p - r is done before p; only the
/// previous row's path costs are kept (memory W * D per direction).
fn accumulate_path(
    cost: &[u8],
    grey: &Grey,
    levels: usize,
    penalties: Penalties,
    (dx, dy): (i64, i64),
    sum: &mut [u16],
) {
    let (w, h) = (grey.width, grey.height);
    let ys: Vec<usize> = if dy >= 0 {
        (0..h).collect()
    } else {
        (0..h).rev().collect()
    };
    let xs: Vec<usize> = if dx >= 0 {
        (0..w).collect()
    } else {
        (0..w).rev().collect()
    };
    let mut prev = vec![0u16; w * levels];
    let mut cur = vec![0u16; w * levels];
    let mut prev_min = vec![0u16; w];
    let mut cur_min = vec![0u16; w];
    // The predecessor's costs with a sentinel at each end, so d - 1 and d + 1 need no checks.
    let sentinel = u16::MAX / 2;
    let mut pred = vec![sentinel; levels + 2];
    for (row, &y) in ys.iter().enumerate() {
        for &x in &xs {
            let at = (y * w + x) * levels;
            let cell = &cost[at..at + levels];
            let px = x as i64 - dx;
            let has_pred = (0..w as i64).contains(&px) && (dy == 0 || row > 0);
            let mut best = u16::MAX;
            if has_pred {
                let px = px as usize;
                let (source, source_min, py) = if dy == 0 {
                    (&cur, &cur_min, y)
                } else {
                    (&prev, &prev_min, (y as i64 - dy) as usize)
                };
                pred[1..=levels].copy_from_slice(&source[px * levels..(px + 1) * levels]);
                let pm = source_min[px];
                let di = grey.data[y * w + x] - grey.data[py * w + px];
                let jump = pm + penalties.p2_at(di);
                let p1 = penalties.p1;
                let out = &mut cur[x * levels..(x + 1) * levels];
                for (d, (o, &c)) in out.iter_mut().zip(cell).enumerate() {
                    let step = pred[d].min(pred[d + 2]) + p1;
                    *o = c as u16 + pred[d + 1].min(step).min(jump) - pm;
                    best = best.min(*o);
                }
            } else {
                let out = &mut cur[x * levels..(x + 1) * levels];
                for (o, &c) in out.iter_mut().zip(cell) {
                    *o = c as u16;
                    best = best.min(*o);
                }
            }
            cur_min[x] = best;
            let out = &cur[x * levels..(x + 1) * levels];
            for (s, &v) in sum[at..at + levels].iter_mut().zip(out) {
                *s += v;
            }
        }
        if dy != 0 {
            std::mem::swap(&mut prev, &mut cur);
            std::mem::swap(&mut prev_min, &mut cur_min);
        }
    }
}
