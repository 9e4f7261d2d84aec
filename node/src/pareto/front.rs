//! The Pareto front of operating points on (latency, quality): a point is on the front when
//! no other point is at least as fast and at least as good, and strictly better in one of
//! the two. Points with a non-finite latency or quality are on no front and dominate none.

/// Which way a quality score improves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Better {
    /// Higher is better (PSNR, SSIM).
    Higher,
    /// Lower is better (AbsRel, LPIPS).
    Lower,
}

/// For each `(latency, quality)` point, whether it is on the front.
pub fn front(points: &[(f64, f64)], better: Better) -> Vec<bool> {
    let good = |q: f64| match better {
        Better::Higher => q,
        Better::Lower => -q,
    };
    let finite = |&(l, q): &(f64, f64)| l.is_finite() && q.is_finite();
    points
        .iter()
        .map(|p| {
            finite(p)
                && !points.iter().filter(|o| finite(o)).any(|o| {
                    let (faster_eq, better_eq) = (o.0 <= p.0, good(o.1) >= good(p.1));
                    faster_eq && better_eq && (o.0 < p.0 || good(o.1) > good(p.1))
                })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dominated_points_are_off_the_front() {
        // (ms, PSNR): a fast poor point, a slow good one, one dominated by the second.
        let pts = [(10.0, 15.0), (80.0, 22.5), (90.0, 22.0), (50.0, 14.0)];
        assert_eq!(front(&pts, Better::Higher), [true, true, false, false]);
        // Lower-is-better: the same points read as AbsRel.
        let pts = [(10.0, 0.18), (80.0, 0.14), (90.0, 0.15), (85.0, 0.13)];
        assert_eq!(front(&pts, Better::Lower), [true, true, false, true]);
    }

    #[test]
    fn ties_and_non_finite_points() {
        // Two equal points dominate neither; an equally fast but worse one is dominated.
        let pts = [(10.0, 20.0), (10.0, 20.0), (10.0, 19.0)];
        assert_eq!(front(&pts, Better::Higher), [true, true, false]);
        let pts = [(f64::NAN, 30.0), (10.0, f64::INFINITY), (20.0, 1.0)];
        assert_eq!(front(&pts, Better::Higher), [false, false, true]);
        assert!(front(&[], Better::Lower).is_empty());
    }
}
