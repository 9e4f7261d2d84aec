//! From the aggregated costs to a disparity map: winner-take-all, a parabola fit for
//! sub-pixel disparity, the uniqueness test, the left-right consistency check, a
//! confidence per pixel, and a 3x3 median filter. Rejected pixels hold NaN.

use rayon::prelude::*;

/// The tests that decide whether a pixel keeps its disparity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Checks {
    /// The best cost must beat the best cost away from d±1 by this fraction.
    pub uniqueness_ratio: f32,
    /// Largest |d_L(x) - d_R(x - d_L)| in pixels that passes the left-right check.
    pub lr_tolerance: f32,
    /// Relative uniqueness margin at which the margin part of the confidence reaches 1.
    pub margin_for_full_confidence: f32,
}

/// Winner-take-all on one row's aggregated costs (`[x][d]`, `width x levels`) with the
/// uniqueness and left-right checks, into `disparity` (NaN where rejected) and `confidence`
/// (0 there). The right image's disparity is read from the same costs, d_R(x) = argmin_d
/// S(x + d, d), as Hirschmüller proposes, which saves a second aggregation.
pub fn select_row(
    row: &[u16],
    levels: usize,
    checks: Checks,
    disparity: &mut [f32],
    confidence: &mut [f32],
) {
    let width = disparity.len();
    let right = right_disparities(row, width, levels);
    for x in 0..width {
        let costs = &row[x * levels..(x + 1) * levels];
        (disparity[x], confidence[x]) = pick(costs, x, &right, checks).unwrap_or((f32::NAN, 0.0));
    }
}

/// The winning disparity of each right-image pixel of one row (integer, the smallest on a
/// tie), in one pass over the row in memory order: left pixel x at disparity d votes for
/// right pixel x - d.
fn right_disparities(row: &[u16], width: usize, levels: usize) -> Vec<u16> {
    let mut best = vec![u16::MAX; width];
    let mut arg = vec![0u16; width];
    for (x, costs) in row.chunks_exact(levels).enumerate().take(width) {
        let reach = levels.min(x + 1);
        for (d, &c) in costs[..reach].iter().enumerate() {
            let xr = x - d;
            if c < best[xr] {
                best[xr] = c;
                arg[xr] = d as u16;
            }
        }
    }
    arg
}

/// The disparity and confidence at left pixel `x`, or `None` if a check rejects it.
fn pick(costs: &[u16], x: usize, right: &[u16], checks: Checks) -> Option<(f32, f32)> {
    // Only disparities whose match lies inside the right image compete.
    let reach = costs.len().min(x + 1);
    // Plain minima over slices, which the compiler vectorises, then the first position.
    let best = *costs[..reach].iter().min()?;
    let best_d = costs[..reach].iter().position(|&c| c == best)?;
    let lowest = |part: &[u16]| part.iter().copied().min().unwrap_or(u16::MAX);
    let second = lowest(&costs[..best_d.saturating_sub(1)])
        .min(lowest(&costs[(best_d + 2).min(reach)..reach]));
    let margin = (second as f32 - best as f32) / (second as f32).max(1.0);
    if margin <= checks.uniqueness_ratio {
        return None;
    }
    let sub = if best_d > 0 && best_d + 1 < reach {
        let (a, b, c) = (
            costs[best_d - 1] as f32,
            best as f32,
            costs[best_d + 1] as f32,
        );
        let curvature = a - 2.0 * b + c;
        if curvature > 0.0 {
            (0.5 * (a - c) / curvature).clamp(-0.5, 0.5)
        } else {
            0.0
        }
    } else {
        0.0
    };
    let d = best_d as f32 + sub;
    let xr = (x as f32 - d).round();
    if xr < 0.0 {
        return None;
    }
    let lr = (d - right[xr as usize] as f32).abs();
    if lr > checks.lr_tolerance {
        return None;
    }
    let margin_part = (margin / checks.margin_for_full_confidence.max(1e-6)).min(1.0);
    let lr_part = 1.0 / (1.0 + lr);
    Some((d, (margin_part * lr_part).clamp(1e-3, 1.0)))
}

/// 3x3 median of the valid disparities around each valid pixel; invalid pixels stay NaN,
/// so the filter removes speckles without growing the valid area.
pub fn median3(disparity: &[f32], width: usize, height: usize) -> Vec<f32> {
    let mut out = vec![f32::NAN; disparity.len()];
    out.par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let mut window = Vec::with_capacity(9);
            for (x, o) in row.iter_mut().enumerate() {
                if disparity[y * width + x].is_nan() {
                    continue;
                }
                window.clear();
                for ny in y.saturating_sub(1)..(y + 2).min(height) {
                    for nx in x.saturating_sub(1)..(x + 2).min(width) {
                        let v = disparity[ny * width + nx];
                        if !v.is_nan() {
                            window.push(v);
                        }
                    }
                }
                window.sort_by(f32::total_cmp);
                *o = window[window.len() / 2];
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const CHECKS: Checks = Checks {
        uniqueness_ratio: 0.05,
        lr_tolerance: 1.0,
        margin_for_full_confidence: 0.5,
    };

    #[test]
    fn a_symmetric_minimum_gives_its_integer_and_a_skewed_one_shifts() {
        let right = vec![2u16; 8];
        let costs = [50u16, 40, 10, 40, 50, 60, 60, 60];
        let (d, conf) = pick(&costs, 6, &right, CHECKS).unwrap();
        assert!((d - 2.0).abs() < 1e-6 && conf > 0.5);
        let skewed = [50u16, 30, 10, 40, 50, 60, 60, 60];
        let (d, _) = pick(&skewed, 6, &right, CHECKS).unwrap();
        assert!((d - 1.9).abs() < 1e-3, "{d}");
    }

    #[test]
    fn an_ambiguous_minimum_is_rejected() {
        let right = vec![2u16; 8];
        let costs = [10u16, 40, 10, 40, 50, 60, 60, 60];
        assert!(pick(&costs, 6, &right, CHECKS).is_none());
    }

    #[test]
    fn the_median_keeps_holes_and_removes_a_speckle() {
        let mut d = vec![5.0f32; 9];
        d[4] = 40.0;
        d[0] = f32::NAN;
        let m = median3(&d, 3, 3);
        assert!(m[0].is_nan());
        assert_eq!(m[4], 5.0);
    }
}
