//! The matching cost: a census transform of the grey image and the Hamming distance between
//! census strings. Census compares each pixel with its neighbours only, so it is blind to
//! gain and offset differences between the two cameras, the usual choice for SGM.

use rayon::prelude::*;

use crate::frame::RgbImage;

/// Half width of the census window (9 columns).
const HALF_W: i32 = 4;
/// Half height of the census window (7 rows).
const HALF_H: i32 = 3;
/// The largest census cost: the window's pixel count less the centre (62 bits).
pub const MAX_CENSUS_COST: u8 = ((2 * HALF_W + 1) * (2 * HALF_H + 1) - 1) as u8;

/// A grey image in [0, 255] (Rec. 601 luma), the scale the adaptive P2 and census use.
#[derive(Clone, Debug)]
pub struct Grey {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` values, row major.
    pub data: Vec<f32>,
}

impl Grey {
    /// Luma of an RGB image; non-finite values count as black so bad input cannot poison
    /// the comparisons.
    pub fn from_rgb(image: &RgbImage) -> Self {
        let data = image
            .data
            .chunks_exact(3)
            .map(|c| {
                let v = 255.0 * (0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]);
                if v.is_finite() {
                    v.clamp(0.0, 255.0)
                } else {
                    0.0
                }
            })
            .collect();
        Self {
            width: image.width as usize,
            height: image.height as usize,
            data,
        }
    }

    /// The value at (x, y) with coordinates clamped into the image (replicated border).
    fn at_clamped(&self, x: i32, y: i32) -> f32 {
        let x = x.clamp(0, self.width as i32 - 1) as usize;
        let y = y.clamp(0, self.height as i32 - 1) as usize;
        self.data[y * self.width + x]
    }
}

/// The 9x7 census string of every pixel: bit k is set where the k-th neighbour is darker
/// than the centre (borders replicated).
pub fn census(grey: &Grey) -> Vec<u64> {
    let (w, h) = (grey.width, grey.height);
    let mut out = vec![0u64; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, code) in row.iter_mut().enumerate() {
                let centre = grey.data[y * w + x];
                let mut bits = 0u64;
                for dy in -HALF_H..=HALF_H {
                    for dx in -HALF_W..=HALF_W {
                        if dx == 0 && dy == 0 {
                            continue;
                        }
                        let v = grey.at_clamped(x as i32 + dx, y as i32 + dy);
                        bits = (bits << 1) | u64::from(v < centre);
                    }
                }
                *code = bits;
            }
        });
    out
}

/// The matching costs of one row, `[x][d]` with `levels` disparities, into `out`: the
/// Hamming distance between the left census at x and the right census at x - d. Where x - d
/// falls off the image the cost is [`MAX_CENSUS_COST`], so those disparities never win on
/// their own. Rows are computed when the aggregation reaches them, so no `W x H x D` cost
/// volume is ever held. On x86-64 CPUs with POPCNT (nearly all) the count is one
/// instruction instead of the baseline target's bit arithmetic, which took a third of the
/// matcher's instructions.
pub fn cost_row(left: &[u64], right: &[u64], levels: usize, out: &mut [u8]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("popcnt") {
        // SAFETY: the CPU was just found to support POPCNT, the only feature enabled.
        return unsafe { cost_row_popcnt(left, right, levels, out) };
    }
    cost_row_portable(left, right, levels, out);
}

/// [`cost_row`] compiled with POPCNT enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "popcnt")]
fn cost_row_popcnt(left: &[u64], right: &[u64], levels: usize, out: &mut [u8]) {
    cost_row_portable(left, right, levels, out);
}

/// [`cost_row`] for any CPU; inlined into each caller so it takes on its target features.
#[inline(always)]
fn cost_row_portable(left: &[u64], right: &[u64], levels: usize, out: &mut [u8]) {
    for (x, costs) in out.chunks_exact_mut(levels).enumerate() {
        let reach = levels.min(x + 1);
        for (d, c) in costs[..reach].iter_mut().enumerate() {
            *c = (left[x] ^ right[x - d]).count_ones() as u8;
        }
        costs[reach..].fill(MAX_CENSUS_COST);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shifted_image_matches_at_its_shift() {
        let (w, h) = (32usize, 9usize);
        let pattern = |x: usize, y: usize| ((x * 37 + y * 91) % 17) as f32 * 10.0;
        let left = Grey {
            width: w,
            height: h,
            data: (0..w * h).map(|i| pattern(i % w, i / w)).collect(),
        };
        let right = Grey {
            width: w,
            height: h,
            data: (0..w * h).map(|i| pattern(i % w + 3, i / w)).collect(),
        };
        let (l, r) = (census(&left), census(&right));
        let mut cost = vec![0u8; w * 8];
        cost_row(&l[4 * w..5 * w], &r[4 * w..5 * w], 8, &mut cost);
        let x = 16;
        let costs = &cost[x * 8..(x + 1) * 8];
        assert_eq!(costs[3], 0);
        assert!(costs.iter().enumerate().all(|(d, &c)| d == 3 || c > 0));
        assert_eq!(MAX_CENSUS_COST, 62);
    }
}
