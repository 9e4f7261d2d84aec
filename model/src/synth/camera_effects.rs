//! What a real camera does to the light before the network sees it, applied to a rendered
//! image in this order: exposure and white balance (per-channel gain), vignetting, optical
//! blur, sensor noise, monochrome conversion, 8-bit quantisation and JPEG compression.
//! Depth and LiDAR are untouched: only the images are spoiled.

use std::io::Cursor;

use glam::DVec3;
use image::codecs::jpeg::JpegEncoder;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::randomise::CameraLook;
use crate::frame::RgbImage;

/// Spoils `image` as a camera of `look` would, with `gain` (one camera's per-channel gain)
/// and noise drawn from `rng`. Values stay in [0, 1].
pub fn apply(image: &mut RgbImage, look: &CameraLook, gain: DVec3, rng: &mut ChaCha8Rng) {
    let (w, h) = (image.width as usize, image.height as usize);
    if w == 0 || h == 0 {
        return;
    }
    let (cx, cy) = (0.5 * (w as f64 - 1.0), 0.5 * (h as f64 - 1.0));
    let corner = (cx * cx + cy * cy).max(1e-9);
    for y in 0..h {
        for x in 0..w {
            let r2 = ((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)) / corner;
            let fall = 1.0 - look.vignetting * r2;
            let px = &mut image.data[3 * (y * w + x)..3 * (y * w + x) + 3];
            for (c, v) in px.iter_mut().enumerate() {
                *v = (*v as f64 * gain[c] * fall) as f32;
            }
        }
    }
    if look.blur_px > 0.05 {
        blur(image, look.blur_px);
    }
    if look.noise > 0.0 {
        for v in &mut image.data {
            *v += (gaussian(rng) * look.noise) as f32;
        }
    }
    if look.grey {
        for px in image.data.chunks_exact_mut(3) {
            let luma = 0.299 * px[0] + 0.587 * px[1] + 0.114 * px[2];
            px.fill(luma);
        }
    }
    for v in &mut image.data {
        *v = (v.clamp(0.0, 1.0) * 255.0).round() / 255.0;
    }
    if let Some(quality) = look.jpeg_quality {
        jpeg_round_trip(image, quality);
    }
}

/// A standard normal sample (Box-Muller).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Separable Gaussian blur of standard deviation `sigma` pixels, edges clamped.
fn blur(image: &mut RgbImage, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let norm: f32 = kernel.iter().sum();
    let (w, h) = (image.width as i64, image.height as i64);
    for horizontal in [true, false] {
        let src = image.data.clone();
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0.0f32; 3];
                for (k, weight) in kernel.iter().enumerate() {
                    let o = k as i64 - radius;
                    let (sx, sy) = if horizontal {
                        ((x + o).clamp(0, w - 1), y)
                    } else {
                        (x, (y + o).clamp(0, h - 1))
                    };
                    let i = 3 * (sy * w + sx) as usize;
                    for (s, v) in sum.iter_mut().zip(&src[i..i + 3]) {
                        *s += weight * v;
                    }
                }
                let i = 3 * (y * w + x) as usize;
                for (out, s) in image.data[i..i + 3].iter_mut().zip(sum) {
                    *out = s / norm;
                }
            }
        }
    }
}

/// Encodes the image as JPEG at `quality` and decodes it again, keeping its artefacts.
fn jpeg_round_trip(image: &mut RgbImage, quality: u8) {
    let bytes: Vec<u8> = image
        .data
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    let mut encoded = Vec::new();
    let encoder = JpegEncoder::new_with_quality(Cursor::new(&mut encoded), quality);
    let decoded = image::ImageEncoder::write_image(
        encoder,
        &bytes,
        image.width,
        image.height,
        image::ExtendedColorType::Rgb8,
    )
    .ok()
    .and_then(|()| image::load_from_memory_with_format(&encoded, image::ImageFormat::Jpeg).ok());
    // Encoding an in-memory RGB8 buffer of the right size cannot fail; if it ever did, the
    // image simply stays uncompressed.
    if let Some(decoded) = decoded {
        let rgb = decoded.to_rgb8();
        if rgb.dimensions() == (image.width, image.height) {
            for (v, b) in image.data.iter_mut().zip(rgb.as_raw()) {
                *v = *b as f32 / 255.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn plain() -> CameraLook {
        CameraLook {
            gain_left: DVec3::ONE,
            gain_right: DVec3::ONE,
            noise: 0.0,
            blur_px: 0.0,
            vignetting: 0.0,
            jpeg_quality: None,
            grey: false,
        }
    }

    fn ramp(w: u32, h: u32) -> RgbImage {
        let mut image = RgbImage::new(w, h);
        for (i, v) in image.data.iter_mut().enumerate() {
            *v = ((i * 37) % 256) as f32 / 255.0;
        }
        image
    }

    #[test]
    fn each_effect_does_what_it_says_and_stays_in_range() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let base = ramp(40, 24);
        let mut same = base.clone();
        apply(&mut same, &plain(), DVec3::ONE, &mut rng);
        assert_eq!(same, base, "no effect on 8-bit values");
        let looks = [
            CameraLook {
                vignetting: 0.4,
                ..plain()
            },
            CameraLook {
                blur_px: 1.0,
                ..plain()
            },
            CameraLook {
                noise: 0.03,
                ..plain()
            },
            CameraLook {
                jpeg_quality: Some(40),
                ..plain()
            },
            CameraLook {
                grey: true,
                ..plain()
            },
        ];
        for look in looks {
            let mut image = base.clone();
            apply(&mut image, &look, DVec3::new(1.5, 1.0, 0.6), &mut rng);
            assert_ne!(image, base);
            assert!(image
                .data
                .iter()
                .all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
        }
        let mut grey = base.clone();
        apply(&mut grey, &looks[4], DVec3::ONE, &mut rng);
        assert!(grey.data.chunks(3).all(|p| p[0] == p[1] && p[1] == p[2]));
    }

    #[test]
    fn empty_saturated_and_tiny_images_are_safe() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let all = CameraLook {
            vignetting: 0.45,
            blur_px: 1.0,
            noise: 0.03,
            jpeg_quality: Some(35),
            ..plain()
        };
        for (w, h, v) in [(0, 0, 0.0), (1, 1, 1.0), (16, 8, 0.0), (16, 8, 1.0)] {
            let mut image = RgbImage::new(w, h);
            image.data.fill(v);
            apply(&mut image, &all, DVec3::splat(1.6), &mut rng);
            assert!(image
                .data
                .iter()
                .all(|x| x.is_finite() && (0.0..=1.0).contains(x)));
        }
    }
}
