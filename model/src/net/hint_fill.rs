//! `sgm_fill`: SGM's hints made dense before the network and the snap read them. SGM leaves
//! unmatched what its left-right check and uniqueness ratio reject: half-occlusions beside
//! a nearer surface and weak texture inside one surface. Along its row, such a pixel takes
//! the smaller (farther) of the nearest matches to its left and to its right, the
//! textbook fill of a left-right check's rejections: at a half-occlusion the hidden surface
//! is the farther one, and inside a weakly textured surface both sides lie on it. On the
//! generated validation drives the network alone got most such pixels of a desk wrong where
//! the fill gets them right (`results/setting_choices/sgm_fill/`).

use super::guidance::SgmHints;

/// `hints` with every unmatched pixel (NaN, not positive or not finite) filled along its
/// row: the smaller of the nearest matched disparities to its left and to its right, the
/// one side's where only one side has a match; a row without a match stays unmatched.
/// Only disparities SGM matched on the same row are ever written, so the fill adds no
/// value outside the map's own range.
pub fn fill_rows(mut hints: SgmHints) -> SgmHints {
    let width = hints.width.max(1);
    let matched = |d: f32| d.is_finite() && d > 0.0;
    let mut from_left = vec![f32::NAN; width];
    for row in hints.disparity.chunks_mut(width) {
        let mut last = f32::NAN;
        for (x, &d) in row.iter().enumerate() {
            if matched(d) {
                last = d;
            }
            from_left[x] = last;
        }
        let mut next = f32::NAN;
        for x in (0..row.len()).rev() {
            if matched(row[x]) {
                next = row[x];
                continue;
            }
            row[x] = match (matched(from_left[x]), matched(next)) {
                (true, true) => from_left[x].min(next),
                (true, false) => from_left[x],
                (false, true) => next,
                (false, false) => f32::NAN,
            };
        }
    }
    hints
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hints(disparity: Vec<f32>, width: usize) -> SgmHints {
        SgmHints {
            height: disparity.len() / width.max(1),
            disparity,
            width,
            fx_baseline: 100.0,
        }
    }

    #[test]
    fn a_gap_takes_the_farther_side_and_a_border_its_one_side() {
        let n = f32::NAN;
        let filled = fill_rows(hints(vec![n, 30.0, n, n, 10.0, n], 6));
        assert_eq!(filled.disparity, vec![30.0, 30.0, 10.0, 10.0, 10.0, 10.0]);
    }

    #[test]
    fn rows_are_filled_apart_and_a_row_without_matches_stays_unmatched() {
        let n = f32::NAN;
        let filled = fill_rows(hints(vec![n, n, n, 5.0, n, 7.0], 3));
        assert!(filled.disparity[..3].iter().all(|d| d.is_nan()));
        assert_eq!(filled.disparity[3..], [5.0, 5.0, 7.0]);
    }

    #[test]
    fn what_is_not_a_match_is_filled_and_never_copied() {
        // Zero, negative, infinite and NaN disparities are unmatched; the extremes a match
        // can take (the smallest positive, the largest finite) are copied as they are.
        let filled = fill_rows(hints(
            vec![
                f32::MIN_POSITIVE,
                0.0,
                -3.0,
                f32::INFINITY,
                f32::NAN,
                f32::MAX,
            ],
            6,
        ));
        let d = &filled.disparity;
        assert_eq!(d[0], f32::MIN_POSITIVE);
        assert!(d[1..5].iter().all(|&v| v == f32::MIN_POSITIVE));
        assert_eq!(d[5], f32::MAX);
    }

    #[test]
    fn empty_and_degenerate_maps_pass_through() {
        assert!(fill_rows(hints(Vec::new(), 0)).disparity.is_empty());
        assert!(fill_rows(hints(Vec::new(), 4)).disparity.is_empty());
        // A map whose length is not a whole number of rows: the last, short row is filled
        // on its own.
        let filled = fill_rows(hints(vec![1.0, f32::NAN, f32::NAN, 2.0, f32::NAN], 3));
        assert_eq!(filled.disparity, vec![1.0, 1.0, 1.0, 2.0, 2.0]);
    }
}
