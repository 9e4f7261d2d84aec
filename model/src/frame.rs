//! Images, depth maps and stereo frames: the data types every reader, generator,
//! reconstructor and metric shares.

use glam::{DAffine3, DVec3};
use renderer::{Camera, Intrinsics};

/// An RGB image with values in [0, 1], row major, channels interleaved. Values are the
/// 8-bit PNG values divided by 255 (no gamma conversion), the convention of 3DGS training.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` values.
    pub data: Vec<f32>,
}

impl RgbImage {
    /// A black image.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            data: vec![0.0; 3 * width as usize * height as usize],
        }
    }

    /// From interleaved 8-bit RGB (`3 * width * height` bytes).
    pub fn from_rgb8(width: u32, height: u32, bytes: &[u8]) -> Self {
        debug_assert_eq!(bytes.len(), 3 * width as usize * height as usize);
        Self {
            width,
            height,
            data: bytes.iter().map(|&b| b as f32 / 255.0).collect(),
        }
    }

    /// As interleaved 8-bit RGB: clamped to [0, 1] and rounded.
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.data
            .iter()
            .map(|&v| renderer::picture::unit_to_u8(v))
            .collect()
    }

    /// The colour at pixel (x, y).
    pub fn pixel(&self, x: u32, y: u32) -> [f32; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
}

/// An RGB image as interleaved 8-bit values, rows packed: how images are read from PNG
/// and travel as `rgb8` messages, a quarter of [`RgbImage`]'s floats.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rgb8Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` bytes.
    pub data: Vec<u8>,
}

impl Rgb8Image {
    /// The image as values in [0, 1] (bytes / 255).
    pub fn to_rgb(&self) -> RgbImage {
        RgbImage::from_rgb8(self.width, self.height, &self.data)
    }
}

/// A per-pixel depth map in metres along the camera z axis; 0 marks "no measurement", as in
/// the KITTI depth benchmarks, so sparse LiDAR depth and dense depth share one type.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthMap {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` depths, row major; 0 where unknown.
    pub data: Vec<f32>,
}

impl DepthMap {
    /// A map with no measurement anywhere.
    pub fn empty(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            data: vec![0.0; width as usize * height as usize],
        }
    }

    /// How many pixels hold a measurement.
    pub fn valid_count(&self) -> usize {
        self.data.iter().filter(|d| **d > 0.0).count()
    }

    /// This map at `width` x `height`, each pixel taking the stored pixel its centre falls
    /// in (depth must not be averaged across edges); itself when the size is already that.
    pub fn nearest(self, width: u32, height: u32) -> Self {
        if (width, height) == (self.width, self.height) || self.data.is_empty() {
            return self;
        }
        let pick = |i: u32, out: u32, stored: u32| {
            (((i as f64 + 0.5) * stored as f64 / out as f64) as u32).min(stored - 1) as usize
        };
        let data = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| {
                self.data[pick(y, height, self.height) * self.width as usize
                    + pick(x, width, self.width)]
            })
            .collect();
        Self {
            width,
            height,
            data,
        }
    }
}

/// A rectified stereo rig: both cameras share `intrinsics` and the right camera sits
/// `baseline` metres along the left camera's +x axis, as after KITTI-360's rectification.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoRig {
    /// Intrinsics of both rectified cameras.
    pub intrinsics: Intrinsics,
    /// Distance between the two camera centres in metres.
    pub baseline: f64,
}

/// Which camera of the rig.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Side {
    /// `image_00`, the reference camera of the poses.
    Left,
    /// `image_01`.
    Right,
}

impl StereoRig {
    /// The pose (camera-to-world) of one camera of the rig given the left camera's pose.
    pub fn camera_to_world(&self, left_to_world: DAffine3, side: Side) -> DAffine3 {
        match side {
            Side::Left => left_to_world,
            Side::Right => left_to_world * DAffine3::from_translation(DVec3::X * self.baseline),
        }
    }

    /// The renderer camera for one camera of the rig, expressed in a local frame whose
    /// camera-to-world is `origin` (a bin's first left camera). The relative pose is formed
    /// in f64, so frames kilometres from the world origin lose nothing when cast to f32.
    pub fn local_camera(&self, origin: DAffine3, left_to_world: DAffine3, side: Side) -> Camera {
        let rel = origin.inverse() * self.camera_to_world(left_to_world, side);
        let rotation = glam::DQuat::from_mat3(&rel.matrix3).as_quat();
        Camera::from_camera_to_world(self.intrinsics, rotation, rel.translation.as_vec3())
    }
}

/// One synchronised stereo frame of a sequence: rectified images and the left camera's
/// pose in the world frame (f64; KITTI-360's `cam0_to_world`).
#[derive(Clone, Debug, PartialEq)]
pub struct StereoFrame {
    /// The frame number in the sequence (the `%010d` of the file names).
    pub index: u32,
    /// Rectified left image (`image_00`).
    pub left: RgbImage,
    /// Rectified right image (`image_01`).
    pub right: RgbImage,
    /// Left camera to world.
    pub left_to_world: DAffine3,
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, Vec3};

    #[test]
    fn local_cameras_are_exact_far_from_the_world_origin() {
        let rig = StereoRig {
            intrinsics: Intrinsics::from_hfov(64, 32, 90.0),
            baseline: 0.6,
        };
        // Camera looking along world +x, 100 km out; the next frame 1.25 m further on.
        let rotation = DMat3::from_cols(-DVec3::Y, -DVec3::Z, DVec3::X);
        let far = DVec3::new(1.0e5, -2.0e5, 35.0);
        let origin = DAffine3::from_mat3_translation(rotation, far);
        let next = DAffine3::from_mat3_translation(rotation, far + DVec3::X * 1.25);
        let left = rig.local_camera(origin, next, Side::Left);
        let right = rig.local_camera(origin, next, Side::Right);
        assert!(
            (left.position - Vec3::new(0.0, 0.0, 1.25))
                .abs()
                .max_element()
                < 1e-6
        );
        assert!(
            (right.position - Vec3::new(0.6, 0.0, 1.25))
                .abs()
                .max_element()
                < 1e-6
        );
        assert!((left.rotation.to_cols_array().iter())
            .zip(glam::Mat3::IDENTITY.to_cols_array())
            .all(|(a, b)| (a - b).abs() < 1e-6));
    }
}
