//! Remap tables: for each pixel of an output image, the source-image coordinate it samples
//! (f32 x and y, pixel centres at integers, as OpenCV's `CV_32FC1` maps), built once per
//! calibration; and the bilinear sampling of an RGB image through one.
//!
//! [`RemapTable::rectify`] is OpenCV's `initUndistortRectifyMap` (rectified pixel, `(P₃
//! R)⁻¹`, the lens model, K); [`RemapTable::distort`] the reverse, the raw image a camera
//! with this calibration would have taken of a rectified one (for test data and generated
//! drives). [`RemapTable::remap`] is `cv::remap` with `INTER_LINEAR` and `BORDER_CONSTANT`
//! 0: each of the four taps that falls outside the source reads as black, so a pixel whose
//! coordinate is off the source by a pixel or more (or not finite: huge coefficients, rays
//! the lens cannot image) is black.

use glam::DVec2;
use model::frame::Rgb8Image;
use rayon::prelude::*;
use thiserror::Error;

use super::camera::CameraModel;

/// The source coordinate of each output pixel, row major.
#[derive(Clone, Debug, PartialEq)]
pub struct RemapTable {
    width: u32,
    height: u32,
    map: Vec<[f32; 2]>,
}

/// Why an image cannot go through a table.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum RemapError {
    /// The image is not the size the table was built for.
    #[error(
        "image is {width}x{height} but the calibration is for {expected_width}x{expected_height}"
    )]
    Size {
        /// The table's width.
        expected_width: u32,
        /// The table's height.
        expected_height: u32,
        /// The image's width.
        width: u32,
        /// The image's height.
        height: u32,
    },
    /// The image's bytes are not `3 * width * height`.
    #[error("rgb8 image {width}x{height} holds {len} bytes, not 3 a pixel")]
    Data {
        /// The image's width.
        width: u32,
        /// The image's height.
        height: u32,
        /// Its byte count.
        len: usize,
    },
}

impl RemapTable {
    /// The rectification table of `camera`: rectified pixel to the raw pixel it samples.
    pub fn rectify(camera: &CameraModel) -> Self {
        let ray_from_rectified = camera.ray_from_rectified();
        Self::build(camera.width(), camera.height(), |px| {
            camera.raw_of_rectified(&ray_from_rectified, px)
        })
    }

    /// The distortion table of `camera`: raw pixel to the rectified pixel it sees, so that
    /// remapping a rectified image gives the raw image this camera would have taken.
    pub fn distort(camera: &CameraModel) -> Self {
        Self::build(camera.width(), camera.height(), |px| {
            camera.rectified_of_raw(px)
        })
    }

    /// A `width` x `height` table of `source(pixel)` (NaN where it is `None`).
    fn build(width: u32, height: u32, source: impl Fn(DVec2) -> Option<DVec2> + Sync) -> Self {
        let mut map = vec![[0.0f32; 2]; width as usize * height as usize];
        map.par_chunks_mut(width as usize)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, out) in row.iter_mut().enumerate() {
                    *out = match source(DVec2::new(x as f64, y as f64)) {
                        Some(s) => [s.x as f32, s.y as f32],
                        None => [f32::NAN; 2],
                    };
                }
            });
        Self { width, height, map }
    }

    /// Output (and source) columns.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Output (and source) rows.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The source coordinates `[x, y]` of every output pixel, row major; NaN where the
    /// pixel has none.
    pub fn coordinates(&self) -> &[[f32; 2]] {
        &self.map
    }

    /// `src` sampled through the table, bilinear, black outside `src`; `src` must be the
    /// calibration's size.
    pub fn remap(&self, src: &Rgb8Image) -> Result<Rgb8Image, RemapError> {
        check_image(self.width, self.height, src)?;
        let (w, h) = (src.width as usize, src.height as usize);
        let mut data = vec![0u8; 3 * w * h];
        data.par_chunks_mut(3 * w)
            .zip(self.map.par_chunks(w))
            .for_each(|(row, coords)| {
                for (out, c) in row.chunks_exact_mut(3).zip(coords) {
                    sample(&src.data, w, h, c[0], c[1], out);
                }
            });
        Ok(Rgb8Image {
            width: self.width,
            height: self.height,
            data,
        })
    }
}

/// `image` must be `width` x `height` with 3 bytes a pixel.
pub(super) fn check_image(width: u32, height: u32, image: &Rgb8Image) -> Result<(), RemapError> {
    if (image.width, image.height) != (width, height) {
        return Err(RemapError::Size {
            expected_width: width,
            expected_height: height,
            width: image.width,
            height: image.height,
        });
    }
    if image.data.len() != 3 * width as usize * height as usize {
        return Err(RemapError::Data {
            width,
            height,
            len: image.data.len(),
        });
    }
    Ok(())
}

/// Bilinear sample of the packed RGB `src` (`w` x `h`) at `(x, y)` into `out`, taps outside
/// `src` black, the result rounded to nearest (ties to even, as `cv::remap`). Written
/// without `floor` and `round`, which are library calls on x86-64's baseline instruction set
/// and took half the time.
fn sample(src: &[u8], w: usize, h: usize, x: f32, y: f32, out: &mut [u8]) {
    // Also false for NaN.
    if !(x > -1.0 && y > -1.0 && x < w as f32 && y < h as f32) {
        out.fill(0);
        return;
    }
    let (x0, y0) = (floor(x), floor(y));
    let (ax, ay) = (x - x0 as f32, y - y0 as f32);
    let weights = [
        (1.0 - ax) * (1.0 - ay),
        ax * (1.0 - ay),
        (1.0 - ax) * ay,
        ax * ay,
    ];
    let mut acc = [0.0f32; 3];
    if x0 >= 0 && y0 >= 0 && (x0 as usize) + 1 < w && (y0 as usize) + 1 < h {
        let i = 3 * (y0 as usize * w + x0 as usize);
        let (top, bottom) = (&src[i..i + 6], &src[i + 3 * w..i + 3 * w + 6]);
        for (c, a) in acc.iter_mut().enumerate() {
            *a = weights[0] * top[c] as f32
                + weights[1] * top[3 + c] as f32
                + weights[2] * bottom[c] as f32
                + weights[3] * bottom[3 + c] as f32;
        }
    } else {
        for (tap, weight) in weights.iter().enumerate() {
            let (tx, ty) = (x0 + (tap & 1) as i32, y0 + (tap >> 1) as i32);
            if tx < 0 || ty < 0 || tx as usize >= w || ty as usize >= h {
                continue;
            }
            let i = 3 * (ty as usize * w + tx as usize);
            for (c, a) in acc.iter_mut().enumerate() {
                *a += weight * src[i + c] as f32;
            }
        }
    }
    for (o, a) in out.iter_mut().zip(acc) {
        // `as` saturates to 0..=255.
        *o = round_ties_even(a) as u8;
    }
}

/// `v.floor()` for `v` in (-1, 2³¹): truncation, one less for negatives with a fraction.
fn floor(v: f32) -> i32 {
    let t = v as i32;
    t - ((t as f32) > v) as i32
}

/// `v.round_ties_even()` for `|v|` below 2²²: adding and taking away 1.5 * 2²³ leaves `v`
/// rounded in the current (nearest-even) rounding mode.
fn round_ties_even(v: f32) -> f32 {
    const SHIFT: f32 = 12_582_912.0;
    (v + SHIFT) - SHIFT
}

#[cfg(test)]
#[path = "table_tests.rs"]
mod tests;
