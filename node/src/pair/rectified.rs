//! Does a pair look rectified? A sparse, cheap match: textured 15x15 patches of the left
//! image on a grid are searched in the right image over every disparity (0 to a third of
//! the width, right image to the left) and a band of rows around their own, scored by
//! zero-mean normalised cross-correlation. A patch counts only when its best match is strong
//! (NCC >= 0.8) and unique in the vertical (every match two or more rows away is at least
//! 0.05 worse), which leaves out patches of vertical edges whose row cannot be told. The
//! median |vertical offset| of the counted patches, refined to a fraction of a pixel by a
//! parabola, is the pair's vertical disparity: 0 for a rectified pair.

use model::baseline::census::Grey;
use model::frame::RgbImage;
use rayon::prelude::*;

/// Half the side of a patch (15x15).
const HALF: i32 = 7;
/// Patch centres per image side at most (a 16x12 grid on a landscape image).
const GRID: usize = 16;
/// Smallest standard deviation (grey levels 0..255) of a patch worth matching.
const MIN_STD: f32 = 4.0;
/// Smallest correlation of an accepted match.
const MIN_NCC: f32 = 0.8;
/// How much better the best match must be than any two or more rows away.
const VERTICAL_MARGIN: f32 = 0.05;
/// Fewer counted patches than this and the check has no answer.
pub const MIN_PATCHES: usize = 8;

/// What the check measured.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct VerticalDisparity {
    /// Median |vertical disparity| in pixels of the images checked; `None` when fewer than
    /// [`MIN_PATCHES`] patches matched (a textureless pair: nothing to tell).
    pub median_px: Option<f32>,
    /// Patches that matched.
    pub patches: usize,
    /// Rows searched above and below a patch's own.
    pub search_rows: u32,
}

/// The rows of the patch at (x, y), left to right within a row; `None` near the border.
fn window(grey: &Grey, x: i32, y: i32) -> Option<impl Iterator<Item = &[f32]> + Clone> {
    let (w, h) = (grey.width as i32, grey.height as i32);
    if x - HALF < 0 || y - HALF < 0 || x + HALF >= w || y + HALF >= h {
        return None;
    }
    Some((y - HALF..=y + HALF).map(move |yy| {
        let row = &grey.data[(yy * w) as usize..][..w as usize];
        &row[(x - HALF) as usize..=(x + HALF) as usize]
    }))
}

/// Grey patch at (x, y) as zero-mean values and their norm; `None` near the border.
fn patch(grey: &Grey, x: i32, y: i32) -> Option<(Vec<f32>, f32)> {
    let mut values: Vec<f32> = window(grey, x, y)?.flatten().copied().collect();
    let mean = values.iter().sum::<f32>() / values.len() as f32;
    values.iter_mut().for_each(|v| *v -= mean);
    let norm = values.iter().map(|v| v * v).sum::<f32>().sqrt();
    Some((values, norm))
}

/// Correlation of a zero-mean patch with the right image's patch at (x, y), computed in
/// place: this runs for every disparity and row searched, so it allocates nothing.
fn ncc(reference: &(Vec<f32>, f32), right: &Grey, x: i32, y: i32) -> Option<f32> {
    let rows = window(right, x, y)?;
    let mean = rows.clone().flatten().sum::<f32>() / reference.0.len() as f32;
    let (mut dot, mut energy) = (0.0f32, 0.0f32);
    for (v, r) in rows.flatten().zip(&reference.0) {
        let c = v - mean;
        dot += c * r;
        energy += c * c;
    }
    let denom = energy.sqrt() * reference.1;
    (denom > 1e-3).then(|| dot / denom)
}

/// The sub-pixel vertical offset of one left patch, if it matches well and uniquely.
fn patch_offset(left: &Grey, right: &Grey, x: i32, y: i32, rows: i32) -> Option<f32> {
    let reference = patch(left, x, y)?;
    let count = reference.0.len() as f32;
    if reference.1 / count.sqrt() < MIN_STD {
        return None;
    }
    let max_d = (left.width as i32 / 3).min(x - HALF);
    // Best correlation per vertical offset, over all disparities.
    let per_row: Vec<f32> = (-rows..=rows)
        .map(|dy| {
            (0..=max_d)
                .filter_map(|d| ncc(&reference, right, x - d, y + dy))
                .fold(f32::NEG_INFINITY, f32::max)
        })
        .collect();
    let (best_i, best) = per_row
        .iter()
        .copied()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let rival = per_row
        .iter()
        .enumerate()
        .filter(|(i, _)| (*i as i32 - best_i as i32).abs() >= 2)
        .map(|(_, v)| *v)
        .fold(f32::NEG_INFINITY, f32::max);
    if !(best >= MIN_NCC && best - rival >= VERTICAL_MARGIN) {
        return None;
    }
    let at = |i: usize| per_row.get(i).copied().filter(|v| v.is_finite());
    let refine = match (best_i.checked_sub(1).and_then(at), at(best_i + 1)) {
        (Some(a), Some(c)) if a - 2.0 * best + c < 0.0 => {
            (0.5 * (a - c) / (a - 2.0 * best + c)).clamp(-0.5, 0.5)
        }
        _ => 0.0,
    };
    Some(best_i as f32 - rows as f32 + refine)
}

/// The vertical disparity of a pair of one size (see the module documentation).
pub fn vertical_disparity(left: &RgbImage, right: &RgbImage) -> VerticalDisparity {
    let (gl, gr) = (Grey::from_rgb(left), Grey::from_rgb(right));
    let rows = (left.height as i32 / 6).clamp(1, 16);
    let margin = HALF + rows;
    let (w, h) = (left.width as i32, left.height as i32);
    let span = |lo: i32, hi: i32| -> Vec<i32> {
        if hi <= lo {
            return Vec::new();
        }
        let n = GRID.min((hi - lo) as usize + 1) as i32;
        (0..n)
            .map(|i| lo + i * (hi - lo) / (n - 1).max(1))
            .collect()
    };
    // Left patches need room for a disparity of at least a few pixels.
    let xs = span(HALF + w / 16, w - HALF - 1);
    let ys = span(margin, h - margin - 1);
    let centres: Vec<(i32, i32)> = ys
        .iter()
        .flat_map(|&y| xs.iter().map(move |&x| (x, y)))
        .collect();
    let mut offsets: Vec<f32> = centres
        .par_iter()
        .filter_map(|&(x, y)| patch_offset(&gl, &gr, x, y, rows))
        .map(f32::abs)
        .collect();
    let patches = offsets.len();
    let median_px = (patches >= MIN_PATCHES).then(|| {
        let mid = patches / 2;
        *offsets.select_nth_unstable_by(mid, f32::total_cmp).1
    });
    VerticalDisparity {
        median_px,
        patches,
        search_rows: rows as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Seeded noise, smoothed over 2x2 so patches correlate under sub-pixel shifts.
    fn noise(width: u32, height: u32, dx: i64, dy: i64) -> RgbImage {
        let hash = |x: i64, y: i64| {
            let mut v = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) as u64;
            v ^= v >> 13;
            v = v.wrapping_mul(0x5bd1_e995);
            (v >> 40) as f32 / (1u64 << 24) as f32
        };
        let data = (0..height as i64)
            .flat_map(|y| (0..width as i64).map(move |x| (x + dx, y + dy)))
            .flat_map(|(x, y)| {
                let v = (hash(x, y) + hash(x + 1, y) + hash(x, y + 1) + hash(x + 1, y + 1)) / 4.0;
                [v; 3]
            })
            .collect();
        RgbImage {
            width,
            height,
            data,
        }
    }

    #[test]
    fn a_rectified_pair_has_none_and_a_shifted_one_its_shift() {
        let left = noise(200, 96, 0, 0);
        let rectified = vertical_disparity(&left, &noise(200, 96, 7, 0));
        assert!(rectified.median_px.unwrap() < 0.1, "{rectified:?}");
        assert!(rectified.patches >= MIN_PATCHES);
        let shifted = vertical_disparity(&left, &noise(200, 96, 7, 5));
        let v = shifted.median_px.unwrap();
        assert!((v - 5.0).abs() < 0.25, "{shifted:?}");
    }

    #[test]
    fn uniform_and_tiny_images_have_no_answer() {
        let flat = RgbImage::new(120, 80);
        assert_eq!(vertical_disparity(&flat, &flat).median_px, None);
        let tiny = noise(5, 3, 0, 0);
        let v = vertical_disparity(&tiny, &tiny);
        assert_eq!((v.median_px, v.patches), (None, 0));
    }
}
