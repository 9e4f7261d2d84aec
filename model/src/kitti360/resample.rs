//! Area (box) resampling of images: each output pixel is the mean of the source area it
//! covers, with partly covered source pixels weighted by the covered fraction. It is exact
//! for whole-number downscales (2x2 -> 1 averages four pixels), never aliases, and keeps the
//! pixel-centre geometry of [`renderer::Intrinsics::scaled`] (output pixel edges map to
//! source edges), so scaled intrinsics and resampled images agree.

use crate::frame::RgbImage;

/// For each of `dst` output cells along one axis, the source cells it covers and their
/// weights (summing to 1).
fn axis_weights(src: u32, dst: u32) -> Vec<Vec<(usize, f64)>> {
    let scale = src as f64 / dst as f64;
    (0..dst)
        .map(|o| {
            let (lo, hi) = (o as f64 * scale, (o + 1) as f64 * scale);
            let first = lo.floor() as usize;
            let last = (hi.ceil() as usize).min(src as usize);
            (first..last)
                .filter_map(|s| {
                    let overlap = (hi.min(s as f64 + 1.0) - lo.max(s as f64)) / scale;
                    (overlap > 0.0).then_some((s, overlap))
                })
                .collect()
        })
        .collect()
}

/// `image` resampled to `width` x `height` by area averaging (a copy when the size is the
/// same). Zero target sizes are raised to 1.
pub fn resample_area(image: &RgbImage, width: u32, height: u32) -> RgbImage {
    let (width, height) = (width.max(1), height.max(1));
    if (width, height) == (image.width, image.height) {
        return image.clone();
    }
    let wx = axis_weights(image.width, width);
    let wy = axis_weights(image.height, height);
    // Horizontal pass into f64 rows, then vertical.
    let sw = image.width as usize;
    let mut rows = vec![0.0f64; 3 * width as usize * image.height as usize];
    for y in 0..image.height as usize {
        for (x, weights) in wx.iter().enumerate() {
            let out = &mut rows[3 * (y * width as usize + x)..][..3];
            for &(s, w) in weights {
                let px = &image.data[3 * (y * sw + s)..][..3];
                for c in 0..3 {
                    out[c] += w * px[c] as f64;
                }
            }
        }
    }
    let mut data = vec![0.0f32; 3 * width as usize * height as usize];
    for (y, weights) in wy.iter().enumerate() {
        for x in 0..width as usize {
            let mut acc = [0.0f64; 3];
            for &(s, w) in weights {
                let px = &rows[3 * (s * width as usize + x)..][..3];
                for c in 0..3 {
                    acc[c] += w * px[c];
                }
            }
            data[3 * (y * width as usize + x)..][..3].copy_from_slice(&acc.map(|v| v as f32));
        }
    }
    RgbImage {
        width,
        height,
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halving_averages_two_by_two_blocks() {
        let data: Vec<f32> = (0..16).flat_map(|i| [i as f32, 0.0, 1.0]).collect();
        let img = RgbImage {
            width: 4,
            height: 4,
            data,
        };
        let half = resample_area(&img, 2, 2);
        // Top-left block holds pixels 0, 1, 4, 5.
        assert!((half.pixel(0, 0)[0] - 2.5).abs() < 1e-6);
        assert!((half.pixel(1, 1)[0] - 12.5).abs() < 1e-6);
        assert!((half.pixel(1, 0)[2] - 1.0).abs() < 1e-6);
        // 4 -> 3 wide: output cell 0 covers source pixel 0 and a third of pixel 1.
        let third = resample_area(&img, 3, 4);
        let expect = (0.0 + 1.0 / 3.0) / (4.0 / 3.0);
        assert!((third.pixel(0, 0)[0] - expect).abs() < 1e-6);
    }
}
