//! Camera images by ray casting: supersampled, box-filtered colour, and exact per-pixel
//! z-depth and class from the ray through each pixel centre.

use glam::{DAffine3, DVec3};
use rayon::prelude::*;
use renderer::Intrinsics;

use super::primitives::Ray;
use super::shading::SurfaceClass;
use super::trace::World;
use crate::frame::{DepthMap, RgbImage};

/// The ray through image point (u, v) (pixel centres at integers) with camera-z component 1,
/// so its hit parameter is the z-depth.
pub fn camera_ray(cam_to_world: &DAffine3, k: &Intrinsics, u: f64, v: f64) -> Ray {
    let x = (u - k.cx as f64) / k.fx as f64;
    let y = (v - k.cy as f64) / k.fy as f64;
    Ray {
        origin: cam_to_world.translation,
        dir: cam_to_world.matrix3 * DVec3::new(x, y, 1.0),
    }
}

/// The colour image seen by a camera, `supersample`² samples per pixel, box filtered.
pub fn render_image(
    world: &World,
    cam_to_world: &DAffine3,
    k: &Intrinsics,
    supersample: u32,
) -> RgbImage {
    let ss = supersample.max(1);
    let order = world.ordering(cam_to_world.translation);
    let pixel_angle = 1.0 / (k.fx as f64 * ss as f64);
    let mut image = RgbImage::new(k.width, k.height);
    let weight = 1.0 / (ss * ss) as f64;
    image
        .data
        .par_chunks_mut(3 * k.width.max(1) as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(3).enumerate() {
                let mut sum = DVec3::ZERO;
                for j in 0..ss {
                    for i in 0..ss {
                        let u = x as f64 + (i as f64 + 0.5) / ss as f64 - 0.5;
                        let v = y as f64 + (j as f64 + 0.5) / ss as f64 - 0.5;
                        let ray = camera_ray(cam_to_world, k, u, v);
                        sum += world.radiance(&order, &ray, pixel_angle).0;
                    }
                }
                let c = (sum * weight).clamp(DVec3::ZERO, DVec3::ONE);
                px.copy_from_slice(&[c.x as f32, c.y as f32, c.z as f32]);
            }
        });
    image
}

/// Exact z-depth (0 for sky) and class of the surface through each pixel centre.
pub fn render_centres(
    world: &World,
    cam_to_world: &DAffine3,
    k: &Intrinsics,
) -> (DepthMap, Vec<SurfaceClass>) {
    let order = world.ordering(cam_to_world.translation);
    let pixel_angle = 1.0 / k.fx as f64;
    let width = k.width as usize;
    let rows: Vec<Vec<(f32, SurfaceClass)>> = (0..k.height as usize)
        .into_par_iter()
        .map(|y| {
            (0..width)
                .map(|x| {
                    let ray = camera_ray(cam_to_world, k, x as f64, y as f64);
                    match world.cast(&order, &ray, f64::INFINITY, pixel_angle) {
                        Some(s) => (s.t as f32, s.class),
                        None => (0.0, SurfaceClass::Sky),
                    }
                })
                .collect()
        })
        .collect();
    let mut depth = DepthMap::empty(k.width, k.height);
    let mut classes = Vec::with_capacity(depth.data.len());
    for (d, (t, c)) in depth.data.iter_mut().zip(rows.into_iter().flatten()) {
        *d = t;
        classes.push(c);
    }
    (depth, classes)
}
