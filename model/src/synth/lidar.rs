//! A Velodyne HDL-64E-like scanner: 64 rings evenly spaced from +2 to -24.9 degrees
//! elevation, a configurable number of azimuth steps, returns up to a maximum range, points
//! in the velodyne frame (x forward, y left, z up) as KITTI's `.bin` records
//! `[x, y, z, reflectance]`.

use glam::{DAffine3, DVec3};
use rayon::prelude::*;

use super::primitives::Ray;
use super::shading::SurfaceClass;
use super::trace::{Surface, World};

/// Number of laser rings.
pub const RINGS: usize = 64;
/// Elevation of the top ring, degrees.
pub const TOP_ELEVATION: f64 = 2.0;
/// Elevation of the bottom ring, degrees.
pub const BOTTOM_ELEVATION: f64 = -24.9;

/// Reflectance in [0, 1] of a surface: bright paint and markings return strongly, glass and
/// dark foliage weakly.
fn reflectance(surface: &Surface) -> f32 {
    let luminance = surface.albedo.dot(DVec3::new(0.299, 0.587, 0.114));
    let r = match surface.class {
        SurfaceClass::Marking => 0.6 + 0.4 * luminance,
        SurfaceClass::Window => 0.05,
        SurfaceClass::Canopy => 0.15 + 0.3 * luminance,
        _ => 0.1 + 0.6 * luminance,
    };
    r.clamp(0.0, 1.0) as f32
}

/// One sweep from the scanner at `velo_to_world`: returns closer than `max_range`, ring by
/// ring, each ring in azimuth order from straight ahead counter-clockwise.
pub fn scan(
    world: &World,
    velo_to_world: &DAffine3,
    azimuth_steps: u32,
    max_range: f64,
) -> Vec<[f32; 4]> {
    let origin = velo_to_world.translation;
    let order = world.ordering(origin);
    let steps = azimuth_steps.max(1);
    let pixel_angle = std::f64::consts::TAU / steps as f64;
    let rings: Vec<Vec<[f32; 4]>> = (0..RINGS)
        .into_par_iter()
        .map(|ring| {
            let frac = ring as f64 / (RINGS - 1) as f64;
            let elevation =
                (TOP_ELEVATION + (BOTTOM_ELEVATION - TOP_ELEVATION) * frac).to_radians();
            (0..steps)
                .filter_map(|a| {
                    let azimuth = std::f64::consts::TAU * a as f64 / steps as f64;
                    let local = DVec3::new(
                        elevation.cos() * azimuth.cos(),
                        elevation.cos() * azimuth.sin(),
                        elevation.sin(),
                    );
                    let ray = Ray {
                        origin,
                        dir: velo_to_world.matrix3 * local,
                    };
                    let surface = world.cast(&order, &ray, max_range, pixel_angle)?;
                    let p = local * surface.t;
                    Some([p.x as f32, p.y as f32, p.z as f32, reflectance(&surface)])
                })
                .collect()
        })
        .collect();
    rings.into_iter().flatten().collect()
}
