//! The view's tests' map Gaussian: a small grey-blue splat at a given position.

use glam::{DVec3, Quat, Vec3};

use crate::fusion::WorldGaussian;

/// A Gaussian of bin 0 at `position`.
pub fn at(position: DVec3) -> WorldGaussian {
    WorldGaussian {
        position,
        log_scale: Vec3::splat(-2.0),
        rotation: Quat::IDENTITY,
        opacity: 0.8,
        color: Vec3::new(0.2, 0.4, 0.6),
        confidence: 0.9,
        bin_id: 0,
    }
}
