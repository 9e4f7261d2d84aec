//! Rectification of raw camera images at the input edge, as ROS's `image_proc` and
//! `stereo_image_proc` do it: a driver that publishes `image_raw` with a full
//! `sensor_msgs/CameraInfo` (K, D, R, P) gets rectified images out, of the same size, with
//! the intrinsics of P, which is what the rest of the node reads.
//!
//! - [`camera`]: one `CameraInfo` checked into a [`CameraModel`] (`plumb_bob`,
//!   `rational_polynomial`, `equidistant`; binning; already-rectified detection).
//! - [`stereo`]: two of them checked as one rectified rig ([`StereoRig`]).
//! - [`distortion`]: the lens models, forward and inverse.
//! - [`table`]: the remap table (OpenCV's `initUndistortRectifyMap`) and bilinear `remap`,
//!   and the reverse table that makes raw images from rectified ones.
//!
//! [`Rectifier`] and [`StereoRectifier`] hold the tables and rebuild them only when a new
//! calibration differs from the last.

pub mod camera;
pub mod distortion;
pub mod stereo;
pub mod table;

use std::borrow::Cow;

pub use camera::{CalibrationError, CameraModel};
pub use distortion::Distortion;
use model::frame::Rgb8Image;
pub use stereo::{StereoError, StereoRig};
pub use table::{RemapError, RemapTable};

/// One camera's rectification: its model and, unless its images are rectified already,
/// its table.
#[derive(Clone, Debug)]
pub struct Rectifier {
    camera: CameraModel,
    table: Option<RemapTable>,
}

impl Rectifier {
    /// The rectifier of `camera`, its table built (none for a camera already rectified).
    pub fn new(camera: CameraModel) -> Self {
        let table = (!camera.is_rectified()).then(|| RemapTable::rectify(&camera));
        Self { camera, table }
    }

    /// The camera it rectifies for.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// Its table; `None` when images pass through.
    pub fn table(&self) -> Option<&RemapTable> {
        self.table.as_ref()
    }

    /// Takes `camera` as the calibration, rebuilding the table only when it differs from
    /// the current one; whether it rebuilt.
    pub fn update(&mut self, camera: CameraModel) -> bool {
        if camera == self.camera {
            return false;
        }
        *self = Self::new(camera);
        true
    }

    /// `raw` rectified: a new image through the table, or `raw` itself when the camera is
    /// rectified already (after the same size check).
    pub fn rectify<'a>(&self, raw: &'a Rgb8Image) -> Result<Cow<'a, Rgb8Image>, RemapError> {
        match &self.table {
            Some(table) => table.remap(raw).map(Cow::Owned),
            None => {
                table::check_image(self.camera.width(), self.camera.height(), raw)?;
                Ok(Cow::Borrowed(raw))
            }
        }
    }
}

/// A stereo rig's two rectifiers.
#[derive(Clone, Debug)]
pub struct StereoRectifier {
    rig: StereoRig,
    left: Rectifier,
    right: Rectifier,
}

impl StereoRectifier {
    /// The rectifiers of `rig`'s two cameras.
    pub fn new(rig: StereoRig) -> Self {
        Self {
            left: Rectifier::new(rig.left.clone()),
            right: Rectifier::new(rig.right.clone()),
            rig,
        }
    }

    /// The rig.
    pub fn rig(&self) -> &StereoRig {
        &self.rig
    }

    /// The left camera's rectifier.
    pub fn left(&self) -> &Rectifier {
        &self.left
    }

    /// The right camera's rectifier.
    pub fn right(&self) -> &Rectifier {
        &self.right
    }

    /// Takes `rig` as the calibration, rebuilding each camera's table only when that
    /// camera's model changed; whether any table was rebuilt.
    pub fn update(&mut self, rig: StereoRig) -> bool {
        let left = self.left.update(rig.left.clone());
        let right = self.right.update(rig.right.clone());
        self.rig = rig;
        left || right
    }

    /// A raw pair rectified (left, right).
    pub fn rectify<'a>(
        &self,
        left: &'a Rgb8Image,
        right: &'a Rgb8Image,
    ) -> Result<(Cow<'a, Rgb8Image>, Cow<'a, Rgb8Image>), RemapError> {
        Ok((self.left.rectify(left)?, self.right.rectify(right)?))
    }
}

#[cfg(test)]
mod test_support;
