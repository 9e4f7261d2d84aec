//! Structural similarity (SSIM) exactly as scikit-image computes it for the feed-forward
//! 3DGS papers: `structural_similarity(a, b, win_size=11, gaussian_weights=True,
//! data_range=1.0, channel_axis=2)`.
//!
//! That call means, per channel: local means, variances and covariance weighted by a
//! normalised 11-tap Gaussian (sigma 1.5; `scipy.ndimage.gaussian_filter` with truncate 3.5
//! gives radius 5) applied separably with scipy's `reflect` boundary (half-sample symmetric,
//! `d c b a | a b c d`); variances scaled by the sample-covariance factor `NP / (NP - 1)`
//! with `NP = 11 * 11`; constants `C1 = (0.01)^2`, `C2 = (0.03)^2`; the map averaged over
//! the interior that lies 5 pixels or more from every border; the three channel means
//! averaged. Sums run in f64 so the result matches scikit-image to about 1e-12.

use rayon::prelude::*;

use super::{check_length, check_pair, MetricError};
use crate::frame::RgbImage;

/// Side of the SSIM window in pixels (11 taps of the Gaussian, radius 5).
pub const SSIM_WINDOW: u32 = 11;

/// [`SSIM_WINDOW`] as a length.
const WINDOW: usize = SSIM_WINDOW as usize;

/// Radius of the window: taps reach this many pixels either side, and the mean SSIM
/// leaves out this many pixels at every border.
const RADIUS: usize = (WINDOW - 1) / 2;

/// Standard deviation of the Gaussian weights in pixels.
const SIGMA: f64 = 1.5;

/// `C1 = (K1 * data_range)^2` with `K1 = 0.01` and data range 1.
const C1: f64 = 0.01 * 0.01;

/// `C2 = (K2 * data_range)^2` with `K2 = 0.03` and data range 1.
const C2: f64 = 0.03 * 0.03;

/// Number of local statistics filtered per pixel: x, y, x*x, y*y, x*y.
const STATS: usize = 5;

/// A per-pixel SSIM map averaged over the three channels, with scipy's reflect boundary
/// at the border (values there are shown in pictures but left out of the mean).
#[derive(Clone, Debug, PartialEq)]
pub struct SsimMap {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` values, row major; 1 where the images agree locally.
    pub data: Vec<f64>,
}

impl SsimMap {
    /// The mean over the interior, cropping `SSIM_WINDOW / 2` = 5 pixels from each border:
    /// scikit-image's mean SSIM. Maps from [`ssim_map`] always have an interior; a map
    /// built by hand with a wrong buffer length or smaller than the window gives an error.
    pub fn interior_mean(&self) -> Result<f64, MetricError> {
        check_length("map", self.width, self.height, 1, self.data.len())?;
        check_window(self.width, self.height)?;
        let (w, h) = (self.width as usize, self.height as usize);
        let (rows, cols) = (RADIUS..h - RADIUS, RADIUS..w - RADIUS);
        let count = rows.len() * cols.len();
        let sum: f64 = rows
            .map(|y| {
                self.data[y * w + cols.start..y * w + cols.end]
                    .iter()
                    .sum::<f64>()
            })
            .sum();
        Ok(sum / count as f64)
    }
}

/// Rejects images smaller than the window, as scikit-image does.
fn check_window(width: u32, height: u32) -> Result<(), MetricError> {
    if width < SSIM_WINDOW || height < SSIM_WINDOW {
        return Err(MetricError::TooSmall {
            width,
            height,
            window: SSIM_WINDOW,
        });
    }
    Ok(())
}

/// Mean SSIM of two RGB images in [0, 1] as scikit-image computes it (see the module
/// doc): 1 for identical images, lower the less alike they are.
/// Errors: different sizes, a malformed buffer, a non-finite value, or an image smaller
/// than the 11 x 11 window.
pub fn ssim(a: &RgbImage, b: &RgbImage) -> Result<f64, MetricError> {
    ssim_map(a, b)?.interior_mean()
}

/// The full SSIM map (per pixel, averaged over channels); [`SsimMap::interior_mean`] of it
/// is [`ssim`]. Same errors as [`ssim`].
pub fn ssim_map(a: &RgbImage, b: &RgbImage) -> Result<SsimMap, MetricError> {
    check_pair(a, b)?;
    check_window(a.width, a.height)?;
    let (w, h) = (a.width as usize, a.height as usize);
    let taps = gaussian_taps();
    let mut data = vec![0.0; w * h];
    let mut stats = vec![0.0; STATS * w * h];
    for channel in 0..3 {
        horizontal_pass(a, b, channel, &taps, &mut stats);
        vertical_pass_add(&stats, w, h, &taps, &mut data);
    }
    data.iter_mut().for_each(|v| *v /= 3.0);
    Ok(SsimMap {
        width: a.width,
        height: a.height,
        data,
    })
}

/// scipy's `_gaussian_kernel1d(1.5, 0, 5)`: `exp(-x^2 / (2 sigma^2))` for x in -5..=5,
/// divided by its sum.
fn gaussian_taps() -> [f64; WINDOW] {
    let mut taps = [0.0; WINDOW];
    for (i, t) in taps.iter_mut().enumerate() {
        let x = i as f64 - RADIUS as f64;
        *t = (-0.5 / (SIGMA * SIGMA) * x * x).exp();
    }
    let sum: f64 = taps.iter().sum();
    taps.iter_mut().for_each(|t| *t /= sum);
    taps
}

/// scipy's `reflect` boundary for an index up to `RADIUS` outside `0..n` (`n > RADIUS`):
/// -1 maps to 0, -2 to 1, n to n - 1.
fn reflect(i: isize, n: usize) -> usize {
    if i < 0 {
        (-i - 1) as usize
    } else if i as usize >= n {
        2 * n - 1 - i as usize
    } else {
        i as usize
    }
}

/// `out[i] = sum_k taps[k] * sources[k][i]`: one output line of the separable filter, with
/// `sources[k]` the input line shifted by `k - RADIUS` pixels (along a row or a column).
/// Uses the symmetry of the taps (6 multiplies instead of 11) and keeps the sum in a
/// register per element, so the loop vectorizes.
fn weighted_sum(out: &mut [f64], sources: &[&[f64]; WINDOW], taps: &[f64; WINDOW]) {
    let n = out.len();
    let s: [&[f64]; WINDOW] = std::array::from_fn(|k| &sources[k][..n]);
    for (i, o) in out.iter_mut().enumerate() {
        let mut sum = taps[RADIUS] * s[RADIUS][i];
        for k in 0..RADIUS {
            sum += taps[k] * (s[k][i] + s[WINDOW - 1 - k][i]);
        }
        *o = sum;
    }
}

/// Filters the five statistics of one channel along rows into `out`: `h` rows of
/// `STATS * w` values, the filtered x, y, x*x, y*y, x*y of that row one after another.
fn horizontal_pass(
    a: &RgbImage,
    b: &RgbImage,
    channel: usize,
    taps: &[f64; WINDOW],
    out: &mut [f64],
) {
    let w = a.width as usize;
    let padded_len = w + 2 * RADIUS;
    out.par_chunks_mut(STATS * w).enumerate().for_each_init(
        || vec![0.0; STATS * padded_len],
        |padded, (y, row_out)| {
            let (px, rest) = padded.split_at_mut(padded_len);
            let (py, rest) = rest.split_at_mut(padded_len);
            let (pxx, rest) = rest.split_at_mut(padded_len);
            let (pyy, pxy) = rest.split_at_mut(padded_len);
            for i in 0..padded_len {
                let x = reflect(i as isize - RADIUS as isize, w);
                let at = 3 * (y * w + x) + channel;
                let (u, v) = (a.data[at] as f64, b.data[at] as f64);
                px[i] = u;
                py[i] = v;
                pxx[i] = u * u;
                pyy[i] = v * v;
                pxy[i] = u * v;
            }
            for (stat, out_stat) in padded
                .chunks_exact(padded_len)
                .zip(row_out.chunks_exact_mut(w))
            {
                let sources = std::array::from_fn(|k| &stat[k..k + w]);
                weighted_sum(out_stat, &sources, taps);
            }
        },
    );
}

/// Filters the row-filtered statistics along columns and adds each pixel's SSIM to `map`.
fn vertical_pass_add(stats: &[f64], w: usize, h: usize, taps: &[f64; WINDOW], map: &mut [f64]) {
    let cov_norm = {
        let np = (SSIM_WINDOW * SSIM_WINDOW) as f64;
        np / (np - 1.0)
    };
    let row_len = STATS * w;
    map.par_chunks_mut(w).enumerate().for_each_init(
        || vec![0.0; row_len],
        |acc, (y, map_row)| {
            let sources = std::array::from_fn(|k| {
                let r = reflect(y as isize + k as isize - RADIUS as isize, h);
                &stats[r * row_len..(r + 1) * row_len]
            });
            weighted_sum(acc, &sources, taps);
            let (ux, rest) = acc.split_at(w);
            let (uy, rest) = rest.split_at(w);
            let (uxx, rest) = rest.split_at(w);
            let (uyy, uxy) = rest.split_at(w);
            for x in 0..w {
                let vx = cov_norm * (uxx[x] - ux[x] * ux[x]);
                let vy = cov_norm * (uyy[x] - uy[x] * uy[x]);
                let vxy = cov_norm * (uxy[x] - ux[x] * uy[x]);
                let num = (2.0 * ux[x] * uy[x] + C1) * (2.0 * vxy + C2);
                let den = (ux[x] * ux[x] + uy[x] * uy[x] + C1) * (vx + vy + C2);
                map_row[x] += num / den;
            }
        },
    );
}
