//! Sparse depth from a velodyne scan: points brought into a rectified camera and projected,
//! keeping the nearest point per pixel, as the devkit's `projectVeloToImage` does (it rounds
//! the projection to the nearest pixel centre and keeps `z > 0` inside the image).

use glam::{DAffine3, DVec3};
use renderer::Intrinsics;

use crate::frame::DepthMap;

/// Projects `points` (velodyne frame, reflectance ignored) through `velo_to_camera` into a
/// camera with `intrinsics`: each point with camera z > 0 that rounds to a pixel inside the
/// image writes its z there unless a nearer point already did. Non-finite points are
/// dropped.
pub fn project_depth(
    points: &[[f32; 4]],
    velo_to_camera: &DAffine3,
    intrinsics: &Intrinsics,
) -> DepthMap {
    let (w, h) = (intrinsics.width, intrinsics.height);
    let mut depth = DepthMap::empty(w, h);
    let (fx, fy) = (intrinsics.fx as f64, intrinsics.fy as f64);
    let (cx, cy) = (intrinsics.cx as f64, intrinsics.cy as f64);
    for p in points {
        let c = velo_to_camera.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
        if !c.is_finite() || c.z <= 0.0 {
            continue;
        }
        let u = (fx * c.x / c.z + cx).round();
        let v = (fy * c.y / c.z + cy).round();
        if u < 0.0 || v < 0.0 || u >= w as f64 || v >= h as f64 {
            continue;
        }
        let z = c.z as f32;
        let slot = &mut depth.data[v as usize * w as usize + u as usize];
        if *slot == 0.0 || z < *slot {
            *slot = z;
        }
    }
    depth
}
