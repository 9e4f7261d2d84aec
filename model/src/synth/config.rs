//! Settings of a synthetic sequence: the kind of scene, its size and rig. A street's rig and
//! LiDAR mounting come from [`crate::kitti360::Calibration::synthetic`], KITTI-360's own
//! calibration scaled; a desk or a room has a handheld rig of its own ([`SceneKind::rig`]);
//! a randomised drive ([`Randomisation`]) draws its rig and image size from its seed.

use super::randomise::{DriveLook, Randomisation};
use super::scene_kind::{RigChoice, SceneKind};

/// Why a configuration cannot be generated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SynthConfigError {
    /// The image has no pixels, or more than the generator renders.
    #[error("image size {width}x{height}: each side must be 1-16384 pixels")]
    Size {
        /// Width asked for.
        width: u32,
        /// Height asked for.
        height: u32,
    },
    /// The baseline is not a positive finite length of at most 10 m.
    #[error("baseline {0} m: it must be finite, positive and at most 10 m")]
    Baseline(f64),
    /// The field of view is not strictly between 1 and 170 degrees.
    #[error("horizontal field of view {0} degrees: it must lie in [1, 170]")]
    FieldOfView(f64),
    /// The viewing distance is not a positive finite length of at most 50 m.
    #[error("viewing distance {0} m: it must be finite, in [0.01, 50]")]
    Distance(f64),
    /// The exposure is negative or not finite.
    #[error("exposure {0}: it must be finite and at least 0")]
    Exposure(f64),
    /// Supersampling of zero samples.
    #[error("supersample 0: at least one sample per pixel")]
    Supersample,
}

/// What to generate. Everything else (layout, palette, light, trajectory) follows from
/// `seed` and `scene`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SynthConfig {
    /// Seed of the whole sequence: equal seeds give bit-identical output.
    pub seed: u64,
    /// Number of frames (10 Hz).
    pub frames: u32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Anti-aliasing: `supersample` x `supersample` box-filtered samples per pixel (>= 1).
    pub supersample: u32,
    /// LiDAR azimuth steps over 360 degrees per ring (64 rings).
    pub lidar_azimuth_steps: u32,
    /// LiDAR maximum range in metres.
    pub lidar_max_range: f64,
    /// Domain randomisation (photo textures, lighting, rig, camera effects, floating
    /// objects); `None`: the plain generator. A randomised drive draws its own image size,
    /// so `width` and `height` are then unused.
    pub randomise: Option<Randomisation>,
    /// The kind of scene.
    pub scene: SceneKind,
    /// The rig, when not randomised: `None` takes the kind's own ([`SceneKind::rig`]).
    /// Ignored by randomised drives, which draw theirs.
    pub rig: Option<RigChoice>,
    /// Desk and room: the distance from the camera to what it looks at (the table top along
    /// the optical axis; the far wall), metres; `None` draws it from the kind's range.
    /// Streets ignore it.
    pub view_distance_m: Option<f64>,
    /// Gain on the rendered radiance before it is clipped to [0, 1]: 1 is the scene as lit,
    /// 0 a black (flat) pair, large values a saturated one.
    pub exposure: f64,
}

impl SynthConfig {
    /// The randomised drive's rig and camera look, drawn from the seed (`None` when the
    /// drive is not randomised).
    pub fn look(&self) -> Option<DriveLook> {
        self.randomise
            .map(|r| r.draw(&mut super::stream(self.seed, 4)))
    }

    /// The image size the drive is rendered at: the drawn one when randomised.
    pub fn size(&self) -> (u32, u32) {
        self.look().map_or((self.width, self.height), |l| l.size)
    }

    /// The rig the drive is seen by, as (focal length px, baseline m), when it is not
    /// KITTI-360's (an unrandomised street without [`SynthConfig::rig`] is).
    pub fn chosen_rig(&self) -> Option<(f64, f64)> {
        if let Some(look) = self.look() {
            return Some((look.focal_px, look.baseline_m));
        }
        let rig = self.rig.or(self.scene.rig())?;
        Some((rig.focal_px(self.width), rig.baseline_m))
    }

    /// Checks that the configuration can be generated: a typed error for sizes, rigs,
    /// distances or exposures no camera has.
    pub fn validate(&self) -> Result<(), SynthConfigError> {
        let (width, height) = self.size();
        if !(1..=16384).contains(&width) || !(1..=16384).contains(&height) {
            return Err(SynthConfigError::Size { width, height });
        }
        if self.supersample == 0 {
            return Err(SynthConfigError::Supersample);
        }
        if let Some(rig) = self.rig.filter(|_| self.randomise.is_none()) {
            if !(rig.baseline_m.is_finite() && rig.baseline_m > 0.0 && rig.baseline_m <= 10.0) {
                return Err(SynthConfigError::Baseline(rig.baseline_m));
            }
            if !(1.0..=170.0).contains(&rig.hfov_deg) {
                return Err(SynthConfigError::FieldOfView(rig.hfov_deg));
            }
        }
        if let Some(d) = self.view_distance_m {
            if !(0.01..=50.0).contains(&d) {
                return Err(SynthConfigError::Distance(d));
            }
        }
        if !(self.exposure.is_finite() && self.exposure >= 0.0) {
            return Err(SynthConfigError::Exposure(self.exposure));
        }
        Ok(())
    }
}

impl Default for SynthConfig {
    /// A tiny street: 40 frames at 272 x 72 (KITTI-360's 1408 x 376 scaled by ~0.19).
    fn default() -> Self {
        Self {
            seed: 0,
            frames: 40,
            width: 272,
            height: 72,
            supersample: 2,
            lidar_azimuth_steps: 1024,
            lidar_max_range: 120.0,
            randomise: None,
            scene: SceneKind::Street,
            rig: None,
            view_distance_m: None,
            exposure: 1.0,
        }
    }
}
