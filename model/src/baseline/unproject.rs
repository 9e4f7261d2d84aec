//! From a disparity map to pixel-aligned Gaussians: depth = fx * b / d, one flat disc per
//! kept pixel on its viewing ray, facing the camera, coloured by the left image.

use glam::{Quat, Vec3};
use renderer::{Camera, Gaussian};

use super::{DisparityMap, SgmConfig};
use crate::frame::RgbImage;

/// The Gaussians of one view: every `stride`-th valid pixel whose depth lies in
/// `[min_depth, max_depth]` and whose confidence reaches `min_confidence`, placed in the
/// frame of `camera` (the bin's local frame). Far pixels (sky) are dropped rather than
/// given huge Gaussians, so the map has nothing beyond `max_depth`.
pub fn unproject(
    map: &DisparityMap,
    image: &RgbImage,
    camera: &Camera,
    baseline: f32,
    config: &SgmConfig,
) -> Vec<Gaussian> {
    let k = camera.intrinsics;
    let stride = config.stride.max(1) as usize;
    let to_world = camera.rotation.transpose();
    let orientation = Quat::from_mat3(&to_world).normalize();
    let mut out = Vec::new();
    for y in (0..map.height as usize).step_by(stride) {
        for x in (0..map.width as usize).step_by(stride) {
            let i = y * map.width as usize + x;
            let (d, conf) = (map.disparity[i], map.confidence[i]);
            // NaN disparity or confidence fails both comparisons and is skipped.
            let usable = d > 0.0 && conf >= config.min_confidence;
            if !usable {
                continue;
            }
            let z = k.fx * baseline / d;
            if !z.is_finite() || z < config.min_depth || z > config.max_depth {
                continue;
            }
            let ray = Vec3::new((x as f32 - k.cx) / k.fx, (y as f32 - k.cy) / k.fy, 1.0);
            let footprint = z / k.fx * stride as f32 * config.footprint_scale;
            let scale = Vec3::new(footprint, footprint, footprint * config.thickness);
            // Non-finite input colours become black rather than poisoning the map.
            let c = image.pixel(x as u32, y as u32).map(|v| {
                if v.is_finite() {
                    v.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            });
            out.push(Gaussian {
                mean: to_world * (ray * z) + camera.position,
                log_scale: scale.ln(),
                rotation: orientation,
                opacity: config.opacity_floor + (1.0 - config.opacity_floor) * conf,
                color: Vec3::from_array(c),
                confidence: conf,
            });
        }
    }
    out
}
