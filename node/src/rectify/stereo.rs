//! A stereo pair's two calibrations checked as one rig: after rectification both images
//! must be one pinhole camera (the same fx', fy', cx', cy') displaced along x, as
//! `stereo_image_proc` and the node's reconstruction assume.

use renderer::Intrinsics;
use thiserror::Error;

use super::camera::{CalibrationError, CameraModel};
use crate::msg::sensor_msgs::CameraInfo;

/// How far the two P's may differ in an entry, in pixels (or pixel-metres for Tx and Ty):
/// both come from one `stereoRectify`, printed alike.
pub const STEREO_TOLERANCE: f64 = 1e-3;

/// The left and right cameras of a rectifiable stereo rig.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoRig {
    /// The left camera (P with Tx = Ty = 0).
    pub left: CameraModel,
    /// The right camera (P with Tx = -fx' * baseline).
    pub right: CameraModel,
}

/// Why two `CameraInfo`s make no rectified stereo rig.
#[derive(Debug, Error, PartialEq)]
pub enum StereoError {
    /// The left calibration is unusable.
    #[error("left camera_info")]
    Left(#[source] CalibrationError),
    /// The right calibration is unusable.
    #[error("right camera_info")]
    Right(#[source] CalibrationError),
    /// The two images differ in size.
    #[error("the left images are {}x{} and the right {}x{}; no rectified rig can come from these", left.0, left.1, right.0, right.1)]
    Size {
        /// Left width and height.
        left: (u32, u32),
        /// Right width and height.
        right: (u32, u32),
    },
    /// The rectified intrinsics differ.
    #[error("the rectified projections differ in {what}: left {left}, right {right}; no rectified rig can come from these")]
    Projection {
        /// `fx'`, `fy'`, `cx'` or `cy'`.
        what: &'static str,
        /// The left P's value.
        left: f64,
        /// The right P's value.
        right: f64,
    },
    /// The baseline is not horizontal with the right camera on the right.
    #[error("{side} P has Tx {tx} and Ty {ty}; a rectified rig needs Tx = Ty = 0 on the left and Tx < 0, Ty = 0 on the right (a horizontal baseline); no rectified rig can come from these")]
    Baseline {
        /// `left` or `right`.
        side: &'static str,
        /// P's Tx.
        tx: f64,
        /// P's Ty.
        ty: f64,
    },
}

impl StereoRig {
    /// The rig of a left and a right `CameraInfo`, each checked alone and then together.
    pub fn from_camera_infos(left: &CameraInfo, right: &CameraInfo) -> Result<Self, StereoError> {
        let left = CameraModel::from_camera_info(left).map_err(StereoError::Left)?;
        let right = CameraModel::from_camera_info(right).map_err(StereoError::Right)?;
        if (left.width(), left.height()) != (right.width(), right.height()) {
            return Err(StereoError::Size {
                left: (left.width(), left.height()),
                right: (right.width(), right.height()),
            });
        }
        let (l, r) = (left.p(), right.p());
        for (what, a, b) in [
            ("fx'", l.fx, r.fx),
            ("fy'", l.fy, r.fy),
            ("cx'", l.cx, r.cx),
            ("cy'", l.cy, r.cy),
        ] {
            if (a - b).abs() > STEREO_TOLERANCE {
                return Err(StereoError::Projection {
                    what,
                    left: a,
                    right: b,
                });
            }
        }
        let (ltx, lty) = left.translation();
        if ltx.abs() > STEREO_TOLERANCE || lty.abs() > STEREO_TOLERANCE {
            return Err(StereoError::Baseline {
                side: "left",
                tx: ltx,
                ty: lty,
            });
        }
        let (rtx, rty) = right.translation();
        if rtx >= -STEREO_TOLERANCE || rty.abs() > STEREO_TOLERANCE {
            return Err(StereoError::Baseline {
                side: "right",
                tx: rtx,
                ty: rty,
            });
        }
        Ok(Self { left, right })
    }

    /// The rectified images' intrinsics (P at the published size, binning applied) and the
    /// baseline: what `msg::image::intrinsics_from_camera_info` reads from a rectified
    /// stream, here right for binned streams too.
    pub fn intrinsics(&self) -> (Intrinsics, f64) {
        let p = self.left.p();
        let k = Intrinsics {
            fx: p.fx as f32,
            fy: p.fy as f32,
            cx: p.cx as f32,
            cy: p.cy as f32,
            width: self.left.width(),
            height: self.left.height(),
        };
        (k, self.baseline())
    }

    /// The baseline in the units of P's Tx over pixels (metres for a ROS calibration):
    /// `-Tx / fx'` of the right camera.
    pub fn baseline(&self) -> f64 {
        -self.right.translation().0 / self.right.p().fx
    }
}
