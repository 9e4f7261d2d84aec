//! The node's input limits: how large a message or an image may be, the resolution the
//! reconstructor works at, and which poses and camera calibrations are physically sane.
//! Anything outside them is refused before it costs memory or worker time, and counted under
//! `refused/<reason>` (see [`Refusal::counter`]).
//!
//! The defaults fit a stereo camera up to 4K UHD:
//! - a message holds at most 32 MiB (a 3840x2160 `rgb8` image is 24.9 MB);
//! - an image is at most 4096 columns, 4096 rows and 3840 x 2160 pixels, and not empty; the
//!   declared size is checked from the CDR fields before the pixels are copied;
//! - the reconstructor works at most at 1408 columns and 1408 x 376 pixels (KITTI-360's
//!   rectified size): a larger image is area-averaged down, aspect kept, and the camera's
//!   intrinsics are scaled the same way, so the worker's time and memory per bin are those of
//!   a KITTI-360 frame at most (`stereosplat bench model --width 1408 --height 376` measures
//!   that cost; docs/crashes-and-limits.md, "Input limits");
//! - a pose's position is within 1e7 m of the world origin (poses are f64; bin-local f32
//!   coordinates then keep millimetres);
//! - a camera's focal lengths lie between 0.05 and 100 times the image width, its principal
//!   point within the image extended by half its size on each side, and a stereo baseline is
//!   positive and at most 10 m.

use std::time::Duration;

use glam::DAffine3;
use renderer::Intrinsics;

use crate::msg::sensor_msgs::ImageLayout;

/// The limits every input is checked against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InputLimits {
    /// Largest payload of any input message, bytes.
    pub max_message_bytes: usize,
    /// Widest image accepted, pixels.
    pub max_width: u32,
    /// Tallest image accepted, pixels.
    pub max_height: u32,
    /// Most pixels in one image.
    pub max_pixels: u64,
    /// Widest image the reconstructor is given; wider ones are scaled down.
    pub max_working_width: u32,
    /// Most pixels the reconstructor is given; larger images are scaled down.
    pub max_working_pixels: u64,
    /// Largest distance of a pose's position from the world origin, metres.
    pub max_translation_m: f64,
    /// Smallest focal length as a multiple of the image width.
    pub min_focal_ratio: f64,
    /// Largest focal length as a multiple of the image width.
    pub max_focal_ratio: f64,
    /// Longest stereo baseline, metres.
    pub max_baseline_m: f64,
    /// The snapshot queryable answers at most one query per this interval.
    pub snapshot_interval: Duration,
}

impl Default for InputLimits {
    /// The limits of the module documentation.
    fn default() -> Self {
        Self {
            max_message_bytes: 32 << 20,
            max_width: 4096,
            max_height: 4096,
            max_pixels: 3840 * 2160,
            max_working_width: 1408,
            max_working_pixels: 1408 * 376,
            max_translation_m: 1e7,
            min_focal_ratio: 0.05,
            max_focal_ratio: 100.0,
            max_baseline_m: 10.0,
            snapshot_interval: Duration::from_secs(1),
        }
    }
}

/// Why an input was refused; each reason has its own counter.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Refusal {
    /// The payload is larger than any input may be.
    #[error("message of {bytes} bytes exceeds the limit of {max} bytes")]
    MessageTooLarge {
        /// Its size.
        bytes: usize,
        /// The limit.
        max: usize,
    },
    /// An image declares a size beyond the limits.
    #[error("image {width}x{height} ({step} bytes per row) exceeds the limits ({max_width}x{max_height}, {max_pixels} pixels)")]
    ImageTooLarge {
        /// Columns declared.
        width: u32,
        /// Rows declared.
        height: u32,
        /// Bytes per row declared.
        step: u32,
        /// The width limit.
        max_width: u32,
        /// The height limit.
        max_height: u32,
        /// The pixel limit.
        max_pixels: u64,
    },
    /// An image with no pixel.
    #[error("image {width}x{height} has no pixel")]
    EmptyImage {
        /// Columns declared.
        width: u32,
        /// Rows declared.
        height: u32,
    },
    /// A pose farther from the world origin than the limit.
    #[error("pose at {distance_m:e} m from the origin (limit {max_m:e} m)")]
    PoseOutOfRange {
        /// Its distance.
        distance_m: f64,
        /// The limit.
        max_m: f64,
    },
    /// A camera calibration that no real camera has.
    #[error("camera info refused: {0}")]
    CameraInfo(String),
    /// Two camera infos that no rectified stereo rig can come from (the rig in force, if
    /// any, stays).
    #[error("camera infos refused as a stereo rig: {0}")]
    StereoRig(String),
    /// A frame whose images do not have the size of the camera infos in force.
    #[error("frame of {image:?} pixels does not match the camera's {camera:?}")]
    SizeMismatch {
        /// The images' working size.
        image: (u32, u32),
        /// The camera's working size.
        camera: (u32, u32),
    },
}

impl Refusal {
    /// The counter this refusal adds to: `refused/<reason>`.
    pub fn counter(&self) -> &'static str {
        match self {
            Refusal::MessageTooLarge { .. } => "refused/message_too_large",
            Refusal::ImageTooLarge { .. } => "refused/image_too_large",
            Refusal::EmptyImage { .. } => "refused/image_empty",
            Refusal::PoseOutOfRange { .. } => "refused/pose_out_of_range",
            Refusal::CameraInfo(_) => "refused/camera_info",
            Refusal::StereoRig(_) => "refused/stereo_rig",
            Refusal::SizeMismatch { .. } => "refused/image_size_mismatch",
        }
    }
}

impl InputLimits {
    /// A payload of `bytes` is small enough to decode.
    pub fn check_message(&self, bytes: usize) -> Result<(), Refusal> {
        match bytes > self.max_message_bytes {
            true => Err(Refusal::MessageTooLarge {
                bytes,
                max: self.max_message_bytes,
            }),
            false => Ok(()),
        }
    }

    /// An image's declared size is within the limits (checked before its pixels are copied;
    /// whether the data matches the size is the decoder's check).
    pub fn check_image(&self, layout: &ImageLayout) -> Result<(), Refusal> {
        let (width, height) = (layout.width, layout.height);
        if width == 0 || height == 0 {
            return Err(Refusal::EmptyImage { width, height });
        }
        let rows_bytes = layout.step as u64 * height as u64;
        if width > self.max_width
            || height > self.max_height
            || width as u64 * height as u64 > self.max_pixels
            || rows_bytes > self.max_message_bytes as u64
        {
            return Err(Refusal::ImageTooLarge {
                width,
                height,
                step: layout.step,
                max_width: self.max_width,
                max_height: self.max_height,
                max_pixels: self.max_pixels,
            });
        }
        Ok(())
    }

    /// The size the reconstructor works at for images of `width` x `height`: the same when
    /// within the working limits, else scaled down by one factor on both axes (rounded, at
    /// least 1) to fit them.
    pub fn working_size(&self, width: u32, height: u32) -> (u32, u32) {
        let pixels = width as f64 * height as f64;
        let scale = (self.max_working_width as f64 / width.max(1) as f64)
            .min((self.max_working_pixels as f64 / pixels.max(1.0)).sqrt());
        if scale >= 1.0 {
            return (width, height);
        }
        let scaled = |n: u32| ((n as f64 * scale).floor() as u32).max(1);
        (scaled(width), scaled(height))
    }

    /// A camera-to-world pose lies within the limit of the origin.
    pub fn check_pose(&self, pose: &DAffine3) -> Result<(), Refusal> {
        let distance_m = pose.translation.length();
        // A NaN distance is in no range: refused too.
        if !(..=self.max_translation_m).contains(&distance_m) {
            return Err(Refusal::PoseOutOfRange {
                distance_m,
                max_m: self.max_translation_m,
            });
        }
        Ok(())
    }

    /// A rectified camera's intrinsics (and, for the right camera, its baseline) are those of
    /// a real camera: size within the image limits, focal lengths and principal point in the
    /// ranges of the module documentation, finite in f32.
    pub fn check_camera(&self, k: &Intrinsics, baseline: Option<f64>) -> Result<(), Refusal> {
        let refuse = |why: String| Err(Refusal::CameraInfo(why));
        let (w, h) = (k.width as f64, k.height as f64);
        if k.width == 0 || k.height == 0 {
            return refuse(format!("image size {}x{}", k.width, k.height));
        }
        if k.width > self.max_width
            || k.height > self.max_height
            || k.width as u64 * k.height as u64 > self.max_pixels
        {
            return refuse(format!(
                "image size {}x{} beyond the image limits",
                k.width, k.height
            ));
        }
        let (lo, hi) = (self.min_focal_ratio * w, self.max_focal_ratio * w);
        for (f, name) in [(k.fx, "fx"), (k.fy, "fy")] {
            let f = f as f64;
            if !(lo..=hi).contains(&f) {
                return refuse(format!("{name} = {f:e} outside [{lo}, {hi}] px"));
            }
        }
        for (c, size, name) in [(k.cx, w, "cx"), (k.cy, h, "cy")] {
            let c = c as f64;
            if !(-0.5 * size..=1.5 * size).contains(&c) {
                return refuse(format!(
                    "{name} = {c:e} outside [{}, {}] px",
                    -0.5 * size,
                    1.5 * size
                ));
            }
        }
        if let Some(b) = baseline {
            if !(b > 0.0 && b <= self.max_baseline_m) {
                return refuse(format!(
                    "baseline {b:e} m outside (0, {}] m",
                    self.max_baseline_m
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout(width: u32, height: u32, step: u32) -> ImageLayout {
        ImageLayout {
            width,
            height,
            step,
            data_len: step.saturating_mul(height),
        }
    }

    #[test]
    fn images_are_refused_by_declared_size() {
        let l = InputLimits::default();
        assert_eq!(l.check_image(&layout(1408, 376, 3 * 1408)), Ok(()));
        assert_eq!(l.check_image(&layout(3840, 2160, 3 * 3840)), Ok(()));
        let empty = l.check_image(&layout(0, 4_000_000_000, 0)).unwrap_err();
        assert_eq!(empty.counter(), "refused/image_empty");
        for (w, h, step) in [
            (8000, 8000, 24000),
            (4097, 1, 3 * 4097),
            (4096, 4096, 3 * 4096),
            // A step far beyond the row: the data it declares would exceed the byte limit.
            (100, 100, u32::MAX),
        ] {
            let e = l.check_image(&layout(w, h, step)).unwrap_err();
            assert_eq!(e.counter(), "refused/image_too_large", "{w}x{h}");
        }
        assert!(l.check_message(32 << 20).is_ok());
        assert_eq!(
            l.check_message((32 << 20) + 1).unwrap_err().counter(),
            "refused/message_too_large"
        );
    }

    #[test]
    fn the_working_size_keeps_the_aspect_within_both_limits() {
        let l = InputLimits::default();
        assert_eq!(l.working_size(1408, 376), (1408, 376));
        assert_eq!(l.working_size(136, 40), (136, 40));
        assert_eq!(l.working_size(2000, 2000), (727, 727));
        let (w, h) = l.working_size(3840, 2160);
        assert!(w <= 1408 && (w as u64 * h as u64) <= 1408 * 376, "{w}x{h}");
        assert!((w as f64 / h as f64 - 3840.0 / 2160.0).abs() < 0.01);
        assert_eq!(l.working_size(4096, 1), (1408, 1));
    }

    #[test]
    fn poses_far_from_the_origin_are_refused() {
        let l = InputLimits::default();
        let at = |x: f64| DAffine3::from_translation(glam::DVec3::new(x, 0.0, 0.0));
        assert!(l.check_pose(&at(9.9e6)).is_ok());
        for x in [1e30, 1.1e7, f64::NAN] {
            assert_eq!(
                l.check_pose(&at(x)).unwrap_err().counter(),
                "refused/pose_out_of_range"
            );
        }
    }

    #[test]
    fn implausible_cameras_are_refused() {
        let l = InputLimits::default();
        let k = Intrinsics::from_hfov(1408, 376, 90.0);
        assert!(l.check_camera(&k, None).is_ok());
        assert!(l.check_camera(&k, Some(0.6)).is_ok());
        let bad = [
            (Intrinsics { fx: 1e30, ..k }, None),
            (
                Intrinsics {
                    fx: f32::INFINITY,
                    ..k
                },
                None,
            ),
            (Intrinsics { fy: 10.0, ..k }, None),
            (Intrinsics { cx: -1e6, ..k }, None),
            (Intrinsics { cy: f32::NAN, ..k }, None),
            (Intrinsics { width: 0, ..k }, None),
            (Intrinsics { width: 9000, ..k }, None),
            (k, Some(0.0)),
            (k, Some(1e6)),
        ];
        for (k, b) in bad {
            let e = l.check_camera(&k, b).unwrap_err();
            assert_eq!(e.counter(), "refused/camera_info", "{k:?} {b:?}");
        }
    }
}
