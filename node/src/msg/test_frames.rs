//! Generated pictures for the image codecs' tests: smooth colour gradients, and the same
//! with hard edges and fine detail laid over, so that lossy paths (demosaicing, JPEG) are
//! measured on content like a camera's, plus their PSNR.

use model::frame::Rgb8Image;
use model::metrics::psnr;

/// Smooth gradients: each channel a slow ramp or wave over the frame, every pixel distinct
/// enough that a swapped channel or row shows.
pub fn smooth(width: u32, height: u32) -> Rgb8Image {
    frame(width, height, |x, y| {
        let (u, v) = (x / width.max(1) as f64, y / height.max(1) as f64);
        [
            0.1 + 0.8 * u,
            0.5 + 0.35 * (3.0 * u + 2.0 * v).sin(),
            0.15 + 0.7 * v * (1.0 - 0.5 * u),
        ]
    })
}

/// [`smooth`] with a dark rectangle, a bright disc and a patch of two-pixel stripes: hard
/// edges at every orientation and detail at the sampling limit.
pub fn textured(width: u32, height: u32) -> Rgb8Image {
    let base = smooth(width, height);
    let (w, h) = (width as f64, height as f64);
    frame(width, height, |x, y| {
        let i = 3 * (y as usize * width as usize + x as usize);
        let mut px = [0.0; 3];
        for (c, p) in px.iter_mut().enumerate() {
            *p = base.data[i + c] as f64 / 255.0;
        }
        let (dx, dy) = (x - 0.7 * w, y - 0.5 * h);
        if (0.1 * w..0.35 * w).contains(&x) && (0.2 * h..0.6 * h).contains(&y) {
            px = [0.1, 0.12, 0.2];
        } else if dx * dx + dy * dy < (0.15 * h.min(w)).powi(2) {
            px = [0.95, 0.9, 0.7];
        } else if (0.4 * w..0.5 * w).contains(&x) && y > 0.7 * h {
            let on = (x as u32 / 2 + y as u32 / 2).is_multiple_of(2);
            px = if on { [0.8; 3] } else { [0.3; 3] };
        }
        px
    })
}

/// A frame of `f(x, y)` (pixel coordinates, values in [0, 1]).
fn frame(width: u32, height: u32, f: impl Fn(f64, f64) -> [f64; 3]) -> Rgb8Image {
    let mut data = Vec::with_capacity(3 * width as usize * height as usize);
    for y in 0..height {
        for x in 0..width {
            let px = f(x as f64, y as f64);
            data.extend(px.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8));
        }
    }
    Rgb8Image {
        width,
        height,
        data,
    }
}

/// The PSNR of `b` against `a`, dB (infinite when equal).
pub fn psnr8(a: &Rgb8Image, b: &Rgb8Image) -> f64 {
    psnr(&a.to_rgb(), &b.to_rgb()).expect("two frames of one size")
}
