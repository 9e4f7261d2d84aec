//! One operating point made runnable on the worker: its reconstructor and the input scale
//! the stereo pair is brought to before it.

use model::frame::RgbImage;
use model::kitti360::resample::resample_area;
use model::methods::MethodError;
use model::reconstruct::{Reconstructor, StereoView};
use renderer::{Camera, GaussianSet};

use crate::pipeline::bin_map::bin_map;
use crate::pipeline::operating::OperatingPoint;
use crate::pipeline::self_check::{CheckOutcome, SelfCheck};

/// A point's reconstructor and input scale, as the worker runs them.
pub struct PointRunner {
    /// The point's name (the latency message's `operating_point`).
    pub name: String,
    /// The reconstructor.
    pub reconstructor: Box<dyn Reconstructor + Send>,
    /// Input scale in (0, 1].
    pub scale: f64,
}

impl PointRunner {
    /// `reconstructor` at full input size, named after it.
    pub fn whole(reconstructor: Box<dyn Reconstructor + Send>) -> Self {
        Self {
            name: reconstructor.name().to_string(),
            reconstructor,
            scale: 1.0,
        }
    }

    /// The reconstructor `point` names, at its scale.
    pub fn build(point: &OperatingPoint) -> Result<Self, MethodError> {
        Ok(Self {
            name: point.name.clone(),
            reconstructor: point.method.build()?,
            scale: point.scale,
        })
    }

    /// A bin's map from `views` brought to the point's scale: the worker's
    /// [`bin_map`] path.
    pub fn bin_map(
        &mut self,
        self_check: &mut SelfCheck,
        views: &[StereoView<'_>],
    ) -> (Result<GaussianSet, String>, CheckOutcome) {
        let reconstructor = self.reconstructor.as_mut();
        with_scaled_views(views, self.scale, |views| {
            bin_map(reconstructor, self_check, views)
        })
    }
}

/// `image` and `camera` brought to `scale` times their size (area averaging, intrinsics
/// scaled; at least 1 pixel a side).
fn downscale(image: &RgbImage, camera: &Camera, scale: f64) -> (RgbImage, Camera) {
    let size = |n: u32| ((n as f64 * scale).round() as u32).max(1);
    let (w, h) = (size(image.width), size(image.height));
    let mut camera = *camera;
    camera.intrinsics = camera.intrinsics.scaled(w, h);
    (resample_area(image, w, h), camera)
}

/// `f` called with `views` brought to `scale` times their size (as they are at 1 or
/// more).
pub fn with_scaled_views<R>(
    views: &[StereoView<'_>],
    scale: f64,
    f: impl FnOnce(&[StereoView<'_>]) -> R,
) -> R {
    if scale >= 1.0 {
        return f(views);
    }
    let scaled: Vec<_> = views
        .iter()
        .map(|v| {
            let (left, left_camera) = downscale(v.left, &v.left_camera, scale);
            let (right, right_camera) = downscale(v.right, &v.right_camera, scale);
            (left, right, left_camera, right_camera)
        })
        .collect();
    let small: Vec<StereoView> = scaled
        .iter()
        .map(|(left, right, left_camera, right_camera)| StereoView {
            left,
            right,
            left_camera: *left_camera,
            right_camera: *right_camera,
        })
        .collect();
    f(&small)
}
