//! `sgm_guidance`: guided stereo matching (Poggi et al., CVPR 2019) with the hints taken from
//! SGM's own confident matches on the pair instead of a LiDAR. The network's logits gain a
//! Gaussian bump `height * exp(-(k - k*)^2 / (2 width^2))` over the candidates `k` around
//! the candidate `k*` of the hinted disparity, on the cost-volume cells where SGM matched
//! consistently; elsewhere they are unchanged. Poggi et al. found that such hints let a
//! network trained on synthetic data transfer to real images without retraining; here the
//! hints come from the same SGM run that fits the depth range (`auto_depth_range`), on the
//! first pair only, so they cost no extra matching.

use candle_core::{Device, Result, Tensor};

use super::depth_head::normalised_inverse;
use super::Config;

/// Least share of a cell's pixels SGM must have matched for the cell to be hinted.
const MIN_VALID: f32 = 0.5;
/// Largest spread (max - min, pixels) of a cell's matched disparities for the cell to be
/// hinted: cells across a depth edge or with scattered matches are left to the network.
const MAX_SPREAD: f32 = 2.0;
/// The standard deviation of the bump a hint adds to the logits, in candidates. On the
/// generated validation drives (`scripts/setting_choices.sh`) widths from 1 to 4 changed
/// AbsRel by at most 0.002 on desks, rooms and streets, so the width the shipped weights
/// were trained with is fixed here rather than offered as a setting.
pub const GUIDANCE_WIDTH: f32 = 2.0;

/// SGM's disparities of the first pair at the network's input size, with what turns them
/// into depths.
#[derive(Clone, Debug, PartialEq)]
pub struct SgmHints {
    /// Left-view disparity in pixels, row major, NaN where SGM rejected the match.
    pub disparity: Vec<f32>,
    /// Width of the map (the pair's width).
    pub width: usize,
    /// Rows of the map (the pair's rows).
    pub height: usize,
    /// Focal length times baseline (pixel metres): depth = `fx_baseline / disparity`.
    pub fx_baseline: f32,
}

impl SgmHints {
    /// The right view's disparity map, from the left one: each left match `x` lands on
    /// right pixel `x - d`, the nearer (larger disparity) winning where two land together;
    /// right pixels no left pixel lands on (occluded in the left view) stay NaN.
    fn right_view(&self) -> Vec<f32> {
        let mut right = vec![f32::NAN; self.disparity.len()];
        for (left, out) in self
            .disparity
            .chunks(self.width.max(1))
            .zip(right.chunks_mut(self.width.max(1)))
        {
            for (x, &d) in left.iter().enumerate() {
                let xr = (x as f32 - d).round();
                if !(d.is_finite() && d > 0.0 && xr >= 0.0) {
                    continue;
                }
                let slot = &mut out[xr as usize];
                if !(slot.is_finite() && *slot >= d) {
                    *slot = d;
                }
            }
        }
        right
    }
}

/// How strongly and how widely hints pull the candidates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuidanceStrength {
    /// Peak of the bump added to the logits.
    pub height: f32,
    /// Its standard deviation, in candidates.
    pub width: f32,
}

/// The bumps `(V, D, h, w)` for `views` views on the cost volume's `grid` (cell `(i, j)` is
/// the ray of image pixel `(stride i, stride j)`) over the candidate `depths` (nearest
/// first, uniform in inverse depth): views 0 and 1 (the first pair's left and right) take
/// the hints, later views none (zeros).
pub fn hint_volume(
    hints: &SgmHints,
    depths: &[f64],
    views: usize,
    grid: (usize, usize),
    stride: usize,
    strength: GuidanceStrength,
    device: &Device,
) -> Result<Tensor> {
    let (h, w) = grid;
    let d = depths.len();
    let mut out = vec![0f32; views * d * h * w];
    let candidate = candidate_index(depths, hints.fx_baseline);
    for cell in hinted_cells(hints, views, grid, stride) {
        let Some(k_star) = candidate(cell.disparity) else {
            continue;
        };
        for k in 0..d {
            let z = (k as f32 - k_star) / strength.width.max(1e-3);
            out[((cell.view * d + k) * h + cell.i) * w + cell.j] =
                strength.height * (-0.5 * z * z).exp();
        }
    }
    Tensor::from_vec(out, (views, d, h, w), device)
}

/// With `sgm_snap`: SGM's own depth for the Gaussians it matched, as the heads apply it.
pub struct SnapTargets {
    /// Normalised inverse depth (1 = the nearest candidate, 0 = the farthest) of each
    /// Gaussian's hinted disparity, `(V, 1, Hg, Wg)`; 0 where `mask` is 0.
    pub inverse: Tensor,
    /// 1 where the Gaussian takes `inverse`, 0 where it keeps the network's, `(V, 1, Hg,
    /// Wg)` as `u8`.
    pub mask: Tensor,
}

/// The targets of `sgm_snap` for `views` views on the Gaussians' `grid` (Gaussian `(i, j)`
/// sits on image pixel `(stride i, stride j)`) within the network's `near..far` (`net`, as
/// the heads turn the inverse depth back into metres): a Gaussian of the first pair whose
/// `(stride + 1)`-pixel square SGM matched consistently (the rule of the hint volume's cells)
/// takes the median match, when it lies within the range; later views and the rest keep the
/// network's.
pub fn snap_targets(
    hints: &SgmHints,
    net: &Config,
    views: usize,
    grid: (usize, usize),
    stride: usize,
    device: &Device,
) -> Result<SnapTargets> {
    let (h, w) = grid;
    let mut inverse = vec![0f32; views * h * w];
    let mut mask = vec![0u8; views * h * w];
    let normalised = |disparity: f32| {
        let t = normalised_inverse(hints.fx_baseline as f64 / disparity as f64, net);
        // The ends count as inside though rounding may put them a hair outside.
        (t.is_finite() && (-1e-6..=1.0 + 1e-6).contains(&t)).then_some(t.clamp(0.0, 1.0) as f32)
    };
    for cell in hinted_cells(hints, views, grid, stride) {
        if let Some(t) = normalised(cell.disparity) {
            let at = (cell.view * h + cell.i) * w + cell.j;
            (inverse[at], mask[at]) = (t, 1);
        }
    }
    Ok(SnapTargets {
        inverse: Tensor::from_vec(inverse, (views, 1, h, w), device)?,
        mask: Tensor::from_vec(mask, (views, 1, h, w), device)?,
    })
}

/// A cell of a hinted view and SGM's disparity there.
struct HintedCell {
    view: usize,
    i: usize,
    j: usize,
    disparity: f32,
}

/// The cells of `grid` (cell `(i, j)` on image pixel `(stride i, stride j)`) that SGM hints,
/// in views 0 (the left map) and 1 (the right view's, from it), at most `views` of them.
fn hinted_cells(
    hints: &SgmHints,
    views: usize,
    grid: (usize, usize),
    stride: usize,
) -> Vec<HintedCell> {
    let right = hints.right_view();
    let mut cells = Vec::new();
    for (view, map) in [&hints.disparity, &right]
        .into_iter()
        .enumerate()
        .take(views)
    {
        for i in 0..grid.0 {
            for j in 0..grid.1 {
                if let Some(disparity) = cell_hint(hints, map, i, j, stride) {
                    cells.push(HintedCell {
                        view,
                        i,
                        j,
                        disparity,
                    });
                }
            }
        }
    }
    cells
}

/// The continuous candidate index of a disparity (`None` outside the candidates by more
/// than one step, or not finite): candidates are uniform in inverse depth, so the index is
/// linear in disparity.
fn candidate_index(depths: &[f64], fx_baseline: f32) -> impl Fn(f32) -> Option<f32> + '_ {
    move |disparity: f32| {
        let (first, last) = (*depths.first()?, *depths.last()?);
        let inverse = disparity as f64 / fx_baseline as f64;
        let (a, b) = (1.0 / first, 1.0 / last);
        let k = (inverse - a) / (b - a) * (depths.len() - 1) as f64;
        (k.is_finite() && k >= -1.0 && k <= depths.len() as f64).then_some(k as f32)
    }
}

/// The hinted disparity of cell `(i, j)`: the median of `map`'s matches over the cell's
/// `(stride + 1)`-pixel square, when at least [`MIN_VALID`] of it matched within
/// [`MAX_SPREAD`] pixels.
fn cell_hint(hints: &SgmHints, map: &[f32], i: usize, j: usize, stride: usize) -> Option<f32> {
    let r = stride / 2;
    let rows = (stride * i).saturating_sub(r)..=(stride * i + r);
    let cols = (stride * j).saturating_sub(r)..=(stride * j + r);
    let mut values = Vec::with_capacity(2 * (stride + 1) * (stride + 1));
    let mut total = 0usize;
    for y in rows.filter(|&y| y < hints.height) {
        for x in cols.clone().filter(|&x| x < hints.width) {
            total += 1;
            let v = map[y * hints.width + x];
            if v.is_finite() && v > 0.0 {
                values.push(v);
            }
        }
    }
    if total == 0 || (values.len() as f32) < MIN_VALID * total as f32 {
        return None;
    }
    values.sort_by(f32::total_cmp);
    let spread = values[values.len() - 1] - values[0];
    (spread <= MAX_SPREAD).then(|| values[values.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `width` x `height` map at disparity `d` everywhere, fx * B = 100.
    fn flat_map(width: usize, height: usize, d: f32) -> SgmHints {
        SgmHints {
            disparity: vec![d; width * height],
            width,
            height,
            fx_baseline: 100.0,
        }
    }

    /// Candidates 1..100 m uniform in inverse depth, nearest first (as `candidate_depths`).
    fn depths(n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| 1.0 / (1.0 + (0.01 - 1.0) * k as f64 / (n - 1) as f64))
            .collect()
    }

    const STRENGTH: GuidanceStrength = GuidanceStrength {
        height: 10.0,
        width: 1.0,
    };

    fn volume(hints: &SgmHints, views: usize, depths: &[f64]) -> Vec<f32> {
        let grid = (hints.height / 4, hints.width / 4);
        hint_volume(hints, depths, views, grid, 4, STRENGTH, &Device::Cpu)
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap()
    }

    #[test]
    fn a_plane_pulls_every_cell_of_both_views_to_its_candidate() {
        // Disparity 50 px at fx B = 100: 2 m, inverse 0.5, candidate (0.5 - 1) / (0.01 - 1)
        // * 10 = 5.05 of 11.
        let depths = depths(11);
        let v = volume(&flat_map(32, 16, 50.0), 2, &depths);
        let cells = 4 * 8;
        for view in 0..2 {
            for cell in 0..cells {
                let column: Vec<f32> = (0..11).map(|k| v[(view * 11 + k) * cells + cell]).collect();
                let best = (0..11)
                    .max_by(|&a, &b| column[a].total_cmp(&column[b]))
                    .unwrap();
                // The right view's leftmost columns see no left pixel (x - 50 < 0 for all):
                // no hint there.
                if view == 1 && column.iter().all(|&x| x == 0.0) {
                    continue;
                }
                assert_eq!(best, 5, "view {view} cell {cell}: {column:?}");
                assert!((column[5] - 10.0 * (-0.5f32 * 0.05 * 0.05).exp()).abs() < 1e-3);
            }
        }
    }

    #[test]
    fn the_right_view_takes_the_nearer_of_two_matches_and_nothing_where_occluded() {
        // Row: x = 0..8; left pixels 4 and 6 land on right pixel 2 with disparities 2 and 4.
        let mut hints = flat_map(8, 1, f32::NAN);
        hints.disparity[4] = 2.0;
        hints.disparity[6] = 4.0;
        let right = hints.right_view();
        assert_eq!(right[2], 4.0);
        assert!(right.iter().enumerate().all(|(x, d)| x == 2 || d.is_nan()));
    }

    #[test]
    fn unmatched_scattered_and_far_off_cells_get_no_hint() {
        let depths = depths(11);
        // No match at all.
        assert!(volume(&flat_map(32, 16, f32::NAN), 2, &depths)
            .iter()
            .all(|&x| x == 0.0));
        // Matches 0.1 m away (disparity 1000, far nearer than the nearest candidate) or at
        // disparity 0 (infinitely far) fall outside the candidates.
        for d in [1000.0, 0.0, f32::INFINITY, -5.0] {
            let v = volume(&flat_map(32, 16, d), 2, &depths);
            assert!(v.iter().all(|&x| x == 0.0), "disparity {d}");
        }
        // Alternating 10 and 40 px: every cell of the left view spans 30 px, no consistent
        // match (in the right view only the 10-px matches land: a consistent half).
        let mut scattered = flat_map(32, 16, 10.0);
        for (i, d) in scattered.disparity.iter_mut().enumerate() {
            if i % 2 == 1 {
                *d = 40.0;
            }
        }
        assert!(volume(&scattered, 1, &depths).iter().all(|&x| x == 0.0));
    }

    #[test]
    fn views_after_the_first_pair_and_huge_strengths_stay_finite() {
        let depths = depths(11);
        let hints = flat_map(32, 16, 50.0);
        let grid = (4, 8);
        for strength in [
            GuidanceStrength {
                height: 1e30,
                width: 1e-9,
            },
            GuidanceStrength {
                height: 0.0,
                width: 1e9,
            },
        ] {
            let v = hint_volume(&hints, &depths, 4, grid, 4, strength, &Device::Cpu).unwrap();
            assert_eq!(v.dims(), &[4, 11, 4, 8]);
            let v: Vec<f32> = v.flatten_all().unwrap().to_vec1().unwrap();
            assert!(v.iter().all(|x| x.is_finite()));
            // Views 2 and 3 (a second pair) have no hints.
            assert!(v[2 * 11 * 32..].iter().all(|&x| x == 0.0));
        }
    }

    /// `snap_targets`' inverse depths and mask for `hints` on a `grid` at stride 2 over 4
    /// views, within `tiny`'s 1..100 m (the range of [`depths`]).
    fn snaps(hints: &SgmHints, grid: (usize, usize)) -> (Vec<f32>, Vec<u8>) {
        let net = Config::tiny();
        assert_eq!((net.near, net.far), (1.0, 100.0));
        let t = snap_targets(hints, &net, 4, grid, 2, &Device::Cpu).unwrap();
        let flat = |t: &Tensor| t.flatten_all().unwrap();
        (
            flat(&t.inverse).to_vec1().unwrap(),
            flat(&t.mask).to_vec1().unwrap(),
        )
    }

    #[test]
    fn snaps_take_the_hinted_depth_within_the_candidates_on_the_first_pair_only() {
        let grid = (8, 16);
        let cells = 8 * 16;
        // 50 px at fx B = 100: 2 m, normalised inverse (0.5 - 0.01) / (1 - 0.01).
        let (inverse, mask) = snaps(&flat_map(32, 16, 50.0), grid);
        for (i, (&t, &m)) in inverse.iter().zip(&mask).enumerate() {
            let view = i / cells;
            // The right view's columns left of 50 px see no left pixel: all of them here.
            let expected = view == 0;
            assert_eq!(m == 1, expected, "cell {i}");
            let want = if expected { 0.49 / 0.99 } else { 0.0 };
            assert!((t - want).abs() < 1e-6, "cell {i}: {t}");
        }
        // The range's ends are kept (1 m: 1, 100 m: 0); nearer, farther, zero, infinite,
        // negative and NaN disparities snap nothing.
        for (d, want) in [(100.0, 1.0), (1.0, 0.0)] {
            let (inverse, mask) = snaps(&flat_map(32, 16, d), grid);
            assert_eq!(mask[0], 1, "disparity {d}");
            assert_eq!(inverse[0], want, "disparity {d}");
        }
        for d in [100.5, 0.5, 0.0, f32::INFINITY, -5.0, f32::NAN] {
            let (inverse, mask) = snaps(&flat_map(32, 16, d), grid);
            assert!(mask.iter().all(|&m| m == 0), "disparity {d}");
            assert!(inverse.iter().all(|&t| t == 0.0), "disparity {d}");
        }
    }
}
