//! Seeded test scenes: the same seed gives the same Gaussians on every machine, so tests,
//! benchmarks and the demo render identical inputs without shipping files.

use glam::{Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::camera::Intrinsics;
use crate::gaussians::{Gaussian, GaussianSet};

fn random_rotation(rng: &mut ChaCha8Rng) -> Quat {
    let v = [0; 4].map(|_| rng.random_range(-1.0f32..1.0));
    Quat::from_xyzw(v[0], v[1], v[2], v[3] + 1e-3).normalize()
}

fn random_color(rng: &mut ChaCha8Rng) -> Vec3 {
    Vec3::new(rng.random(), rng.random(), rng.random())
}

/// `n` Gaussians scattered in the view frustum of a camera at the origin looking down +z,
/// at depths 2 to 50 m, each about 0.5 to 4 px across on screen (sizes follow depth).
pub fn random_in_view(seed: u64, n: usize, k: &Intrinsics) -> GaussianSet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut set = GaussianSet::with_capacity(n);
    for _ in 0..n {
        let z: f32 = rng.random_range(2.0..50.0);
        let u: f32 = rng.random_range(-8.0..k.width as f32 + 8.0);
        let v: f32 = rng.random_range(-8.0..k.height as f32 + 8.0);
        let mean = Vec3::new((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z);
        let pixel = z / k.fx;
        let sx: f32 = rng.random_range(0.5..4.0);
        let aniso = Vec3::new(1.0, rng.random_range(0.3..1.0), rng.random_range(0.3..1.0));
        set.push(Gaussian {
            mean,
            log_scale: (aniso * sx * pixel).ln(),
            rotation: random_rotation(&mut rng),
            opacity: rng.random_range(0.05..1.0),
            color: random_color(&mut rng),
            confidence: rng.random(),
        });
    }
    set
}

/// Where a viewing ray of a simple street hits, seen from a camera 1.5 m above the road:
/// the road below the horizon, facades 6 m to either side, the sky (at `max_depth`) above.
/// Returns the depth and the surface's colour (lane markings on the road, window rows on the
/// facades), so rendered pictures read as a street.
fn street_hit(dx: f32, dy: f32, max_depth: f32) -> (f32, Vec3) {
    let road = if dy > 1e-3 { 1.5 / dy } else { f32::INFINITY };
    let facade = if dx.abs() > 1e-3 {
        6.0 / dx.abs()
    } else {
        f32::INFINITY
    };
    let z = road.min(facade).min(max_depth);
    let (x, y) = (dx * z, dy * z);
    let color = if z >= max_depth {
        Vec3::new(0.55, 0.7, 0.9) - Vec3::splat(0.3 * dy.max(-1.0))
    } else if road <= facade {
        let lane = x.abs() < 0.08 && (z % 6.0) < 3.0;
        if lane {
            Vec3::splat(0.9)
        } else {
            Vec3::splat(0.35)
        }
    } else {
        let window = (y.rem_euclid(3.0)) < 1.4 && (z.rem_euclid(4.0)) < 2.2 && y < 0.5;
        let tone = if x > 0.0 {
            Vec3::new(0.7, 0.45, 0.35)
        } else {
            Vec3::new(0.8, 0.75, 0.6)
        };
        if window {
            Vec3::new(0.15, 0.2, 0.3)
        } else {
            tone
        }
    };
    (z, color)
}

/// One pixel-aligned Gaussian per pixel of each view, as a feed-forward model emits them:
/// views are cameras at the origin shifted along x by `baseline` each (a stereo rig), depth
/// from a street-like layout, scale from the pixel footprint. `views = 2` at 544x112 is the
/// paper's input (121,856 Gaussians).
pub fn pixel_aligned(seed: u64, k: &Intrinsics, views: usize, baseline: f32) -> GaussianSet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut set = GaussianSet::with_capacity(views * k.width as usize * k.height as usize);
    for view in 0..views {
        let origin = Vec3::new(view as f32 * baseline, 0.0, 0.0);
        for y in 0..k.height {
            for x in 0..k.width {
                let dx = (x as f32 - k.cx) / k.fx;
                let dy = (y as f32 - k.cy) / k.fy;
                let (z, color) = street_hit(dx, dy, 80.0);
                let z = z * rng.random_range(0.98..1.02);
                let color = color + Vec3::splat(rng.random_range(-0.05..0.05));
                let footprint = z / k.fx;
                set.push(Gaussian {
                    mean: origin + Vec3::new(dx * z, dy * z, z),
                    log_scale: Vec3::splat((footprint * rng.random_range(0.6..1.2)).ln()),
                    rotation: random_rotation(&mut rng),
                    opacity: rng.random_range(0.3..1.0),
                    color,
                    confidence: rng.random(),
                });
            }
        }
    }
    set
}

/// A small scene for gradient checks: `n` Gaussians of moderate size and opacity in front of
/// a camera at the origin, overlapping enough that ordering and occlusion matter.
pub fn small_overlapping(seed: u64, n: usize, k: &Intrinsics) -> GaussianSet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut set = GaussianSet::with_capacity(n);
    for _ in 0..n {
        let z: f32 = rng.random_range(3.0..6.0);
        let u: f32 = rng.random_range(0.2..0.8) * k.width as f32;
        let v: f32 = rng.random_range(0.2..0.8) * k.height as f32;
        let mean = Vec3::new((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z);
        let px = z / k.fx;
        let s = Vec3::new(
            rng.random_range(1.5..5.0),
            rng.random_range(1.5..5.0),
            rng.random_range(1.5..5.0),
        );
        set.push(Gaussian {
            mean,
            log_scale: (s * px).ln(),
            rotation: random_rotation(&mut rng),
            opacity: rng.random_range(0.2..0.9),
            color: random_color(&mut rng),
            confidence: rng.random(),
        });
    }
    set
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_scene() {
        let k = Intrinsics::from_hfov(64, 32, 90.0);
        assert_eq!(random_in_view(7, 100, &k), random_in_view(7, 100, &k));
        assert_ne!(random_in_view(7, 100, &k), random_in_view(8, 100, &k));
        assert_eq!(pixel_aligned(1, &k, 2, 0.6).len(), 2 * 64 * 32);
    }
}
