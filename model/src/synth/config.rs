//! Settings of a synthetic sequence and a KITTI-360-like rig to render it with.

use glam::{DAffine3, DMat3, DVec3};
use renderer::Intrinsics;

use crate::frame::StereoRig;

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
        }
    }
}

/// KITTI-360's rectified perspective camera (`P_rect_00`) at its native 1408 x 376.
// The digits are written as the calibration file publishes them; f32 keeps what it can.
#[allow(clippy::excessive_precision)]
pub const KITTI360_INTRINSICS: Intrinsics = Intrinsics {
    fx: 552.554261,
    fy: 552.554261,
    cx: 682.049453,
    cy: 238.769549,
    width: 1408,
    height: 376,
};

/// KITTI-360's stereo baseline in metres.
pub const KITTI360_BASELINE: f64 = 0.5942;

/// A KITTI-360-like rectified rig scaled to `width` x `height`, for sequences made before a
/// calibration file is at hand.
pub fn kitti360_rig(width: u32, height: u32) -> StereoRig {
    StereoRig {
        intrinsics: KITTI360_INTRINSICS.scaled(width, height),
        baseline: KITTI360_BASELINE,
    }
}

/// A plausible camera-to-velodyne transform: velodyne 0.8 m above and 0.3 m behind the left
/// camera, axes x forward, y left, z up (camera: x right, y down, z forward).
pub fn default_cam_to_velo() -> DAffine3 {
    // Columns: images of the camera axes in velodyne coordinates.
    let rot = DMat3::from_cols(-DVec3::Y, -DVec3::Z, DVec3::X);
    // Camera origin in velodyne coordinates.
    let cam_in_velo = DVec3::new(0.3, 0.0, -0.8);
    DAffine3::from_mat3_translation(rot, cam_in_velo)
}
