//! Domain randomisation: the settings (each a range) that make generated drives vary the way
//! real cameras and places do, and the per-drive draw from them. A network trained on the
//! plain generator has seen one camera, one light model and flat-shaded streets, and fails
//! on real photographs; trained on these drives it has to match real image statistics
//! (photo textures), any rig (intrinsics, baseline, image size), any look (exposure, white
//! balance, noise, blur, vignetting, JPEG, grey cameras) and near geometry (floating objects
//! in front of the street, FlyingThings3D-style).
//!
//! Everything is drawn from the drive's seed: equal seeds still give bit-identical drives.

use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::scene_kind::SceneKind;

/// The ranges the randomisation draws from. `Default` holds the documented ranges
/// (docs/evaluation.md, "Synthetic drives"); every drive draws its own values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Randomisation {
    /// Image sizes (width, height) a drive picks from (all multiples of 8, about 20-28k
    /// pixels, so a training step costs about the same).
    pub sizes: &'static [(u32, u32)],
    /// An image size every drive takes instead of its draw from `sizes` (training data at
    /// one working size). The draw is still made, so a seed keeps the rest of its rig and
    /// look: the field of view and baseline, hence the disparities relative to the width.
    pub fixed_size: Option<(u32, u32)>,
    /// Horizontal field of view, degrees.
    pub hfov_deg: (f64, f64),
    /// Stereo baseline, metres (drawn log-uniformly: phone and OAK-D rigs to wide car rigs).
    pub baseline_m: (f64, f64),
    /// The nearest the scene's surfaces come to the camera, metres, when that is near enough
    /// to bound the rig: the baseline is then drawn no wider than the one that puts this
    /// depth at `NEAREST_DISPARITY_FRACTION` of the image width (a 50 cm rig 20 cm from a
    /// desk would see it over twice the image width apart, matched by nothing). `None`: the
    /// baseline's range alone.
    pub nearest_m: Option<f64>,
    /// Probability that the drive's colours (walls, paints, ground) are drawn at random
    /// instead of from the street palette.
    pub colour_probability: f64,
    /// Probability that a surface (facade, ground band) wears a photo texture (floaters
    /// always do).
    pub photo_probability: f64,
    /// Period of a photo texture on a surface, metres.
    pub photo_period_m: (f64, f64),
    /// Floating textured objects per 15 m road segment.
    pub floaters_per_segment: (u32, u32),
    /// Floater size (largest half extent), metres.
    pub floater_size_m: (f64, f64),
    /// Closest lateral clearance between a floater and the camera's path, metres: the camera
    /// passes floaters this close, so they are seen from ~5 m down to this distance.
    pub floater_clearance_m: (f64, f64),
    /// Exposure gain (log-uniform).
    pub exposure: (f64, f64),
    /// White balance: per-channel gain around 1.
    pub white_balance: f64,
    /// Difference of exposure between the two cameras (relative).
    pub camera_mismatch: f64,
    /// Sensor noise standard deviation (in [0, 1] intensity).
    pub noise: (f64, f64),
    /// Gaussian blur sigma, pixels.
    pub blur_px: (f64, f64),
    /// Vignetting: relative darkening at the image corners.
    pub vignetting: (f64, f64),
    /// Probability that a drive's images go through JPEG, and its quality range.
    pub jpeg_probability: f64,
    /// JPEG quality range (1-100).
    pub jpeg_quality: (u8, u8),
    /// Probability that a drive's camera is monochrome (as OAK-D's stereo pair).
    pub grey_probability: f64,
}

impl Default for Randomisation {
    fn default() -> Self {
        Self {
            sizes: &[
                (272, 72),
                (240, 96),
                (208, 112),
                (192, 128),
                (176, 144),
                (160, 160),
            ],
            fixed_size: None,
            hfov_deg: (45.0, 100.0),
            baseline_m: (0.05, 0.6),
            nearest_m: None,
            colour_probability: 0.5,
            photo_probability: 0.6,
            photo_period_m: (0.5, 6.0),
            floaters_per_segment: (0, 12),
            floater_size_m: (0.2, 1.5),
            floater_clearance_m: (0.3, 2.5),
            exposure: (0.55, 1.6),
            white_balance: 0.15,
            camera_mismatch: 0.08,
            noise: (0.0, 0.03),
            blur_px: (0.0, 1.0),
            vignetting: (0.0, 0.45),
            jpeg_probability: 0.5,
            jpeg_quality: (35, 95),
            grey_probability: 0.15,
        }
    }
}

/// The disparity of a scene's nearest surface, as a fraction of the image width, that a
/// drawn rig stays within ([`Randomisation::nearest_m`]): the third of the width the
/// matchers search at least.
pub const NEAREST_DISPARITY_FRACTION: f64 = 1.0 / 3.0;

/// Image sizes of handheld rigs (desks, rooms): widths 320-1408 at 4:3, 16:10, 16:9 and
/// wide (KITTI-360 and the node's working) aspects, heights multiples of 8.
pub const HANDHELD_SIZES: &[(u32, u32)] = &[
    (320, 240),
    (384, 240),
    (448, 256),
    (544, 112),
    (544, 144),
    (640, 360),
    (640, 480),
    (768, 480),
    (800, 600),
    (960, 544),
    (1024, 768),
    (1152, 720),
    (1280, 720),
    (1408, 376),
    (1408, 792),
];

impl Randomisation {
    /// The ranges a drive of `kind` draws from: the street's are [`Randomisation::default`];
    /// desks and rooms draw handheld rigs ([`HANDHELD_SIZES`], 55-100 degrees, 5-50 cm
    /// baselines log-uniformly) and keep the default looks. A desk's surfaces come to
    /// 0.2 m, so its rigs stay within the width that keeps them matchable
    /// ([`Randomisation::nearest_m`]: 5 cm up to 7-16 cm, by the field of view); a room's,
    /// at 1 m and more, leave every 5-50 cm rig inside the image.
    pub fn for_scene(kind: SceneKind) -> Self {
        let handheld = Self {
            sizes: HANDHELD_SIZES,
            hfov_deg: (55.0, 100.0),
            baseline_m: (0.05, 0.5),
            ..Self::default()
        };
        match kind {
            SceneKind::Street => Self::default(),
            SceneKind::Room => handheld,
            SceneKind::Desk => Self {
                nearest_m: Some(0.2),
                ..handheld
            },
        }
    }

    /// The baseline range of a rig whose horizontal field of view is `hfov` radians:
    /// [`Randomisation::baseline_m`], its top lowered to the widest baseline that keeps
    /// [`Randomisation::nearest_m`] within `NEAREST_DISPARITY_FRACTION` of the width (its
    /// bottom too, when that is narrower still). Disparity over width is `baseline / (2
    /// depth tan(hfov / 2))`, the same at every image size of one lens.
    fn baseline_range(&self, hfov: f64) -> (f64, f64) {
        let (lo, hi) = self.baseline_m;
        let cap = self
            .nearest_m
            .map(|z| NEAREST_DISPARITY_FRACTION * z * 2.0 * (0.5 * hfov).tan())
            .filter(|c| c.is_finite() && *c > 0.0);
        match cap {
            Some(c) if c < hi => (lo.min(c), c),
            _ => (lo, hi),
        }
    }
}

/// One drive's draw: its rig and its camera's look.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveLook {
    /// Image width and height.
    pub size: (u32, u32),
    /// Focal length in pixels (square pixels, principal point at the centre).
    pub focal_px: f64,
    /// Baseline, metres.
    pub baseline_m: f64,
    /// How the images are spoiled.
    pub camera: CameraLook,
    /// The ranges it was drawn from (scene draws use them too).
    pub ranges: Randomisation,
}

/// What the camera does to the rendered radiance, per drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraLook {
    /// Per-channel gain of the left camera (exposure times white balance).
    pub gain_left: DVec3,
    /// Per-channel gain of the right camera.
    pub gain_right: DVec3,
    /// Noise standard deviation.
    pub noise: f64,
    /// Blur sigma in pixels (0: none).
    pub blur_px: f64,
    /// Corner darkening.
    pub vignetting: f64,
    /// JPEG quality, if the drive is compressed.
    pub jpeg_quality: Option<u8>,
    /// Monochrome camera.
    pub grey: bool,
}

/// A uniform draw from `[lo, hi)` (`lo` when the range is empty).
pub(super) fn range(rng: &mut ChaCha8Rng, (lo, hi): (f64, f64)) -> f64 {
    if hi > lo {
        rng.random_range(lo..hi)
    } else {
        lo
    }
}

/// A log-uniform draw from `[lo, hi)`.
pub(super) fn log_range(rng: &mut ChaCha8Rng, (lo, hi): (f64, f64)) -> f64 {
    range(rng, (lo.ln(), hi.ln())).exp()
}

impl Randomisation {
    /// The draw of one drive from `rng` (the drive's own stream).
    pub fn draw(&self, rng: &mut ChaCha8Rng) -> DriveLook {
        let drawn = self.sizes[rng.random_range(0..self.sizes.len().max(1))];
        let size = self.fixed_size.unwrap_or(drawn);
        let hfov = range(rng, self.hfov_deg).to_radians();
        let focal_px = 0.5 * size.0 as f64 / (0.5 * hfov).tan();
        let baseline_m = log_range(rng, self.baseline_range(hfov));
        let exposure = log_range(rng, self.exposure);
        let wb = DVec3::new(
            range(rng, (1.0 - self.white_balance, 1.0 + self.white_balance)),
            1.0,
            range(rng, (1.0 - self.white_balance, 1.0 + self.white_balance)),
        );
        let mismatch = range(
            rng,
            (1.0 - self.camera_mismatch, 1.0 + self.camera_mismatch),
        );
        let jpeg = rng.random_bool(self.jpeg_probability.clamp(0.0, 1.0));
        let (qlo, qhi) = self.jpeg_quality;
        let quality = rng.random_range(qlo.min(qhi)..=qhi.max(qlo)).clamp(1, 100);
        let camera = CameraLook {
            gain_left: wb * exposure,
            gain_right: wb * exposure * mismatch,
            noise: range(rng, self.noise),
            blur_px: range(rng, self.blur_px),
            vignetting: range(rng, self.vignetting),
            jpeg_quality: jpeg.then_some(quality),
            grey: rng.random_bool(self.grey_probability.clamp(0.0, 1.0)),
        };
        DriveLook {
            size,
            focal_px,
            baseline_m,
            camera,
            ranges: *self,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn draws_stay_inside_their_ranges_and_vary() {
        let r = Randomisation::default();
        let looks: Vec<DriveLook> = (0..200)
            .map(|s| r.draw(&mut ChaCha8Rng::seed_from_u64(s)))
            .collect();
        for l in &looks {
            assert!(r.sizes.contains(&l.size));
            assert!((0.05..=0.6).contains(&l.baseline_m));
            let hfov = 2.0 * (0.5 * l.size.0 as f64 / l.focal_px).atan();
            assert!((44.9..=100.1).contains(&hfov.to_degrees()));
            assert!(l.camera.gain_left.min_element() > 0.4);
        }
        let sizes: std::collections::BTreeSet<_> = looks.iter().map(|l| l.size).collect();
        assert_eq!(sizes.len(), r.sizes.len());
        assert!(looks.iter().any(|l| l.camera.grey) && looks.iter().any(|l| !l.camera.grey));
        assert!(looks.iter().any(|l| l.camera.jpeg_quality.is_some()));
        assert!(
            looks.iter().any(|l| l.baseline_m < 0.1) && looks.iter().any(|l| l.baseline_m > 0.4)
        );
    }

    #[test]
    fn handheld_rigs_span_their_ranges() {
        let r = Randomisation::for_scene(SceneKind::Room);
        assert_eq!(
            Randomisation {
                nearest_m: None,
                ..Randomisation::for_scene(SceneKind::Desk)
            },
            r
        );
        assert_eq!(
            Randomisation::for_scene(SceneKind::Street),
            Randomisation::default()
        );
        for &(w, h) in HANDHELD_SIZES {
            assert!(
                (320..=1408).contains(&w) && w % 8 == 0 && h % 8 == 0,
                "{w}x{h}"
            );
            let aspect = w as f64 / h as f64;
            assert!((1.3..=4.9).contains(&aspect), "{w}x{h}");
        }
        let looks: Vec<DriveLook> = (0..400)
            .map(|s| r.draw(&mut ChaCha8Rng::seed_from_u64(s)))
            .collect();
        let (lo, hi) = looks.iter().fold((f64::MAX, 0.0f64), |(a, b), l| {
            (a.min(l.baseline_m), b.max(l.baseline_m))
        });
        assert!(
            (0.05..0.06).contains(&lo) && hi <= 0.5 && hi > 0.45,
            "{lo}..{hi}"
        );
        // Log-uniform: about as many rigs under 15.8 cm (the geometric mean) as over.
        let under = looks.iter().filter(|l| l.baseline_m < 0.158).count();
        assert!((160..240).contains(&under), "{under} of 400 under 15.8 cm");
        let widths: std::collections::BTreeSet<u32> = looks.iter().map(|l| l.size.0).collect();
        assert!(
            widths.contains(&320) && widths.contains(&1408),
            "{widths:?}"
        );
    }

    #[test]
    fn a_fixed_size_keeps_the_rest_of_the_draw() {
        let drawn = Randomisation::for_scene(SceneKind::Desk);
        let fixed = Randomisation {
            fixed_size: Some((544, 112)),
            ..drawn
        };
        for seed in 0..50 {
            let a = drawn.draw(&mut ChaCha8Rng::seed_from_u64(seed));
            let b = fixed.draw(&mut ChaCha8Rng::seed_from_u64(seed));
            assert_eq!(b.size, (544, 112));
            assert_eq!((a.baseline_m, a.camera), (b.baseline_m, b.camera));
            let hfov = |l: &DriveLook| (0.5 * l.size.0 as f64 / l.focal_px).atan();
            assert!((hfov(&a) - hfov(&b)).abs() < 1e-12, "seed {seed}");
        }
    }

    #[test]
    fn desk_rigs_keep_the_nearest_surface_within_a_third_of_the_width() {
        let r = Randomisation::for_scene(SceneKind::Desk);
        let looks: Vec<DriveLook> = (0..400)
            .map(|s| r.draw(&mut ChaCha8Rng::seed_from_u64(s)))
            .collect();
        for l in &looks {
            let disparity = l.focal_px * l.baseline_m / 0.2;
            assert!(
                disparity <= l.size.0 as f64 / 3.0 * (1.0 + 1e-9),
                "{l:?}: {disparity} px at 0.2 m"
            );
            assert!(l.baseline_m >= 0.05 - 1e-12, "{}", l.baseline_m);
        }
        // Wide lenses allow wider rigs: the caps run from about 7 cm (55 degrees) to 16 cm.
        let (lo, hi) = looks.iter().fold((f64::MAX, 0.0f64), |(a, b), l| {
            (a.min(l.baseline_m), b.max(l.baseline_m))
        });
        assert!(
            (0.05..0.055).contains(&lo) && (0.13..0.16).contains(&hi),
            "{lo}..{hi}"
        );
        // The cap changes only the baseline: the rest of each draw is the room's.
        let room = Randomisation {
            nearest_m: None,
            ..r
        };
        for seed in 0..50 {
            let (a, b) = (
                r.draw(&mut ChaCha8Rng::seed_from_u64(seed)),
                room.draw(&mut ChaCha8Rng::seed_from_u64(seed)),
            );
            assert_eq!(
                (a.size, a.focal_px, a.camera),
                (b.size, b.focal_px, b.camera)
            );
            assert!(a.baseline_m <= b.baseline_m);
        }
        // A cap under the range's bottom draws that cap; nonsense caps are ignored.
        let narrow = Randomisation {
            hfov_deg: (10.0, 10.0),
            ..r
        };
        let l = narrow.draw(&mut ChaCha8Rng::seed_from_u64(1));
        assert!(l.baseline_m < 0.05 && l.baseline_m > 0.0);
        for nearest in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let odd = Randomisation {
                nearest_m: Some(nearest),
                ..r
            };
            let b = odd.draw(&mut ChaCha8Rng::seed_from_u64(2)).baseline_m;
            assert!(b.is_finite() && (0.05..=0.5).contains(&b), "{nearest}: {b}");
        }
    }
}
