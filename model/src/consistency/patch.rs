//! Grey-level patches of an [`RgbImage`] and their zero-mean normalised cross-correlation:
//! the photometric comparison of the self-check, insensitive to a gain and an offset between
//! the two cameras (exposure, white level).

use crate::frame::RgbImage;

/// Rec. 601 luma weights: one grey value per pixel, so a colour cast between the cameras
/// matters as little as an exposure difference.
const LUMA: [f32; 3] = [0.299, 0.587, 0.114];

/// A square patch of grey values, `(2 radius + 1)^2` of them, row major.
#[derive(Clone, Debug, Default)]
pub(super) struct Patch {
    values: Vec<f32>,
}

/// Mean and standard deviation of a patch's grey values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Moments {
    /// Mean grey value.
    pub mean: f32,
    /// Population standard deviation (0 for a flat patch).
    pub std: f32,
}

/// An image whose size and data agree, read as grey values.
pub(super) struct Grey<'a> {
    image: &'a RgbImage,
    width: usize,
    height: usize,
}

impl<'a> Grey<'a> {
    /// `image` when its data holds `3 * width * height` finite-or-not values and it is large
    /// enough for one patch of `radius`; `None` otherwise (nothing is sampled from it).
    pub fn new(image: &'a RgbImage, radius: usize) -> Option<Self> {
        let (width, height) = (image.width as usize, image.height as usize);
        let side = 2 * radius + 1;
        let enough = width >= side && height >= side;
        (enough && image.data.len() >= 3 * width * height).then_some(Self {
            image,
            width,
            height,
        })
    }

    /// Columns.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The grey value of pixel (x, y), in range; a non-finite channel reads as 0.
    fn at(&self, x: usize, y: usize) -> f32 {
        let i = 3 * (y * self.width + x);
        let rgb = &self.image.data[i..i + 3];
        let g = rgb[0] * LUMA[0] + rgb[1] * LUMA[1] + rgb[2] * LUMA[2];
        if g.is_finite() {
            g
        } else {
            0.0
        }
    }

    /// The patch of `radius` centred on pixel (x, y), or `None` when it does not lie wholly
    /// inside the image.
    pub fn patch_at(&self, x: i64, y: i64, radius: usize, out: &mut Patch) -> Option<()> {
        let r = radius as i64;
        let inside = x >= r && y >= r && x + r < self.width as i64 && y + r < self.height as i64;
        if !inside {
            return None;
        }
        out.values.clear();
        for py in (y - r)..=(y + r) {
            for px in (x - r)..=(x + r) {
                out.values.push(self.at(px as usize, py as usize));
            }
        }
        Some(())
    }

    /// The patch of `radius` centred on the sub-pixel position (x, y), bilinearly
    /// interpolated, or `None` when any tap falls outside the image (or x, y are not finite).
    pub fn patch_bilinear(&self, x: f32, y: f32, radius: usize, out: &mut Patch) -> Option<()> {
        let r = radius as f32;
        let (x0, y0) = (x - r, y - r);
        let max_x = (self.width - 1) as f32;
        let max_y = (self.height - 1) as f32;
        // `!(a >= b)` is also true for NaN.
        if !(x0 >= 0.0 && y0 >= 0.0 && x + r <= max_x && y + r <= max_y) {
            return None;
        }
        let (fx, fy) = (x0.fract(), y0.fract());
        let (ix, iy) = (x0 as usize, y0 as usize);
        let side = 2 * radius + 1;
        out.values.clear();
        for dy in 0..side {
            let ya = iy + dy;
            let yb = (ya + 1).min(self.height - 1);
            for dx in 0..side {
                let xa = ix + dx;
                let xb = (xa + 1).min(self.width - 1);
                let top = self.at(xa, ya) * (1.0 - fx) + self.at(xb, ya) * fx;
                let bottom = self.at(xa, yb) * (1.0 - fx) + self.at(xb, yb) * fx;
                out.values.push(top * (1.0 - fy) + bottom * fy);
            }
        }
        Some(())
    }
}

impl Patch {
    /// Mean and standard deviation (f64 sums, so a patch of large values loses nothing).
    pub fn moments(&self) -> Moments {
        let n = self.values.len().max(1) as f64;
        let mean = self.values.iter().map(|&v| v as f64).sum::<f64>() / n;
        let var = self
            .values
            .iter()
            .map(|&v| (v as f64 - mean).powi(2))
            .sum::<f64>()
            / n;
        Moments {
            mean: mean as f32,
            std: var.max(0.0).sqrt() as f32,
        }
    }

    /// Zero-mean normalised cross-correlation with `other` (same size) in [-1, 1]; 0 when
    /// either patch is flat (a correlation is not defined there).
    pub fn zncc(&self, other: &Patch) -> f32 {
        let (a, b) = (self.moments(), other.moments());
        if a.std <= 0.0 || b.std <= 0.0 || self.values.len() != other.values.len() {
            return 0.0;
        }
        let n = self.values.len() as f64;
        let cov = self
            .values
            .iter()
            .zip(&other.values)
            .map(|(&x, &y)| (x as f64 - a.mean as f64) * (y as f64 - b.mean as f64))
            .sum::<f64>()
            / n;
        ((cov / (a.std as f64 * b.std as f64)) as f32).clamp(-1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(width: u32, height: u32, gain: f32, offset: f32) -> RgbImage {
        let mut img = RgbImage::new(width, height);
        for y in 0..height {
            for x in 0..width {
                let v = offset + gain * ((x * 7 + y * 13) % 17) as f32 / 17.0;
                let i = 3 * (y * width + x) as usize;
                img.data[i..i + 3].copy_from_slice(&[v, v, v]);
            }
        }
        img
    }

    #[test]
    fn zncc_ignores_gain_and_offset_and_flat_patches_score_zero() {
        let a = ramp(20, 20, 1.0, 0.0);
        let b = ramp(20, 20, 0.4, 0.3);
        let (ga, gb) = (Grey::new(&a, 3).unwrap(), Grey::new(&b, 3).unwrap());
        let (mut pa, mut pb) = (Patch::default(), Patch::default());
        ga.patch_at(8, 9, 3, &mut pa).unwrap();
        gb.patch_bilinear(8.0, 9.0, 3, &mut pb).unwrap();
        assert!((pa.zncc(&pb) - 1.0).abs() < 1e-5, "{}", pa.zncc(&pb));
        let flat = RgbImage::new(20, 20);
        let gf = Grey::new(&flat, 3).unwrap();
        gf.patch_at(8, 9, 3, &mut pb).unwrap();
        assert_eq!(pb.moments().std, 0.0);
        assert_eq!(pa.zncc(&pb), 0.0);
    }

    #[test]
    fn patches_outside_the_image_or_at_nan_positions_are_refused() {
        let a = ramp(20, 20, 1.0, 0.0);
        let g = Grey::new(&a, 3).unwrap();
        let mut p = Patch::default();
        assert!(g.patch_at(2, 9, 3, &mut p).is_none());
        assert!(g.patch_at(17, 9, 3, &mut p).is_none());
        assert!(g.patch_bilinear(16.5, 9.0, 3, &mut p).is_none());
        assert!(g.patch_bilinear(f32::NAN, 9.0, 3, &mut p).is_none());
        assert!(g.patch_bilinear(f32::INFINITY, 9.0, 3, &mut p).is_none());
        // Too small for a patch, or data shorter than the size says.
        assert!(Grey::new(&RgbImage::new(6, 20), 3).is_none());
        let mut short = RgbImage::new(20, 20);
        short.data.truncate(10);
        assert!(Grey::new(&short, 3).is_none());
    }
}
