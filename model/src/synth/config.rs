//! Settings of a synthetic sequence. The rig and LiDAR mounting come from
//! [`crate::kitti360::Calibration::synthetic`], KITTI-360's own calibration scaled, unless
//! the drive is randomised ([`Randomisation`]): then it draws its own rig and image size.

use super::randomise::{DriveLook, Randomisation};

/// What to generate. Everything else (layout, palette, sun, trajectory) follows from `seed`.
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
}

impl Default for SynthConfig {
    /// A tiny sequence: 40 frames at 272 x 72 (KITTI-360's 1408 x 376 scaled by ~0.19).
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
        }
    }
}
