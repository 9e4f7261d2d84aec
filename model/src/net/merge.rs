//! Merging redundant Gaussians of a bin map, so its size follows the scene rather than the
//! pixel count: the network emits one Gaussian per `gaussian_stride` pixels everywhere, but
//! a flat stretch of road, wall or sky is drawn as well by fewer, larger ones.
//!
//! Rule: Gaussians in front of the reference camera are grouped by a key of (image column /
//! `2 stride`, image row / `2 stride`, log depth / `tolerance`, each colour channel /
//! `tolerance`), so a group is at most a 2x2 block of neighbouring Gaussians whose depths
//! agree within about `tolerance` (relative) and whose colours agree within `tolerance`.
//! A group of `n` > 1 becomes one Gaussian at the opacity-weighted mean position and
//! colour, the largest opacity and confidence, the first member's rotation, and its scales
//! times `sqrt(n)` (four Gaussians of a 2x2 block cover twice the extent). Textured or
//! uneven regions keep every Gaussian. Gaussians behind the camera or non-finite are kept
//! as they are.

use std::collections::HashMap;

use glam::Vec3;
use renderer::{Camera, Gaussian, GaussianSet};

/// `set` (in the frame where `camera` is the reference view) with redundant Gaussians
/// merged by the rule in the module documentation; `stride` is the network's Gaussian
/// stride in pixels, `tolerance` the relative depth and absolute colour tolerance.
pub fn merge_redundant(
    set: &GaussianSet,
    camera: &Camera,
    stride: usize,
    tolerance: f32,
) -> GaussianSet {
    if !(tolerance.is_finite() && tolerance > 0.0) || set.is_empty() {
        return set.clone();
    }
    let k = camera.intrinsics;
    let cell = 2.0 * stride.max(1) as f32;
    let mut groups: HashMap<[i64; 6], Vec<usize>> = HashMap::new();
    let mut order: Vec<Result<[i64; 6], usize>> = Vec::with_capacity(set.len());
    for i in 0..set.len() {
        let g = set.get(i);
        let p = camera.rotation * (g.mean - camera.position);
        let key = (p.z > 1e-3 && p.is_finite() && g.color.is_finite()).then(|| {
            let u = k.fx * p.x / p.z + k.cx;
            let v = k.fy * p.y / p.z + k.cy;
            let q = |x: f32, step: f32| (x / step).floor() as i64;
            [
                q(u, cell),
                q(v, cell),
                q(p.z.ln(), tolerance),
                q(g.color.x, tolerance),
                q(g.color.y, tolerance),
                q(g.color.z, tolerance),
            ]
        });
        match key {
            Some(key) => {
                let members = groups.entry(key).or_default();
                if members.is_empty() {
                    order.push(Ok(key));
                }
                members.push(i);
            }
            None => order.push(Err(i)),
        }
    }
    let mut out = GaussianSet::with_capacity(order.len());
    for entry in order {
        match entry {
            Err(i) => out.push(set.get(i)),
            Ok(key) => out.push(merged(set, &groups[&key])),
        }
    }
    out
}

/// One Gaussian standing for `members` (see the module documentation).
fn merged(set: &GaussianSet, members: &[usize]) -> Gaussian {
    let first = set.get(members[0]);
    if members.len() == 1 {
        return first;
    }
    let weight: f32 = members.iter().map(|&i| set.opacities[i].max(1e-6)).sum();
    let mean_of = |f: &dyn Fn(&Gaussian) -> Vec3| {
        members
            .iter()
            .map(|&i| {
                let g = set.get(i);
                f(&g) * g.opacity.max(1e-6)
            })
            .sum::<Vec3>()
            / weight
    };
    let max_of = |f: &dyn Fn(&Gaussian) -> f32| {
        members
            .iter()
            .map(|&i| f(&set.get(i)))
            .fold(f32::MIN, f32::max)
    };
    Gaussian {
        mean: mean_of(&|g| g.mean),
        log_scale: first.log_scale + Vec3::splat(0.5 * (members.len() as f32).ln()),
        rotation: first.rotation,
        opacity: max_of(&|g| g.opacity),
        color: mean_of(&|g| g.color),
        confidence: max_of(&|g| g.confidence),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;
    use renderer::Intrinsics;

    fn camera() -> Camera {
        let k = Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 50.0,
            cy: 50.0,
            width: 100,
            height: 100,
        };
        Camera::from_camera_to_world(k, Quat::IDENTITY, Vec3::ZERO)
    }

    fn at(u: f32, v: f32, depth: f32, color: f32) -> Gaussian {
        Gaussian {
            mean: Vec3::new(
                (u - 50.0) * depth / 100.0,
                (v - 50.0) * depth / 100.0,
                depth,
            ),
            log_scale: Vec3::splat(0.01f32.ln()),
            rotation: Quat::IDENTITY,
            opacity: 0.8,
            color: Vec3::splat(color),
            confidence: 0.5,
        }
    }

    #[test]
    fn a_flat_block_merges_and_texture_and_depth_edges_do_not() {
        let mut set = GaussianSet::default();
        // A flat 2x2 block at 10 m (stride 2: pixels 40.5 and 42.5 share a 4-pixel cell).
        for (u, v) in [(40.5, 40.5), (42.5, 40.5), (40.5, 42.5), (42.5, 42.5)] {
            set.push(at(u, v, 10.0, 0.5));
        }
        // A textured block: colours far apart.
        for (k, (u, v)) in [(60.5, 40.5), (62.5, 40.5)].into_iter().enumerate() {
            set.push(at(u, v, 10.0, 0.2 + 0.5 * k as f32));
        }
        // A depth edge: same colour, 10 m against 20 m.
        set.push(at(60.5, 60.5, 10.0, 0.5));
        set.push(at(62.5, 60.5, 20.0, 0.5));
        // Behind the camera and NaN: kept as they are.
        let mut behind = at(10.5, 10.5, 5.0, 0.5);
        behind.mean.z = -5.0;
        set.push(behind);
        let mut nan = at(12.5, 10.5, 5.0, 0.5);
        nan.mean.x = f32::NAN;
        set.push(nan);
        let out = merge_redundant(&set, &camera(), 2, 0.05);
        assert_eq!(out.len(), 1 + 2 + 2 + 2);
        let m = out.get(0);
        assert!((m.mean.z - 10.0).abs() < 1e-4, "{}", m.mean);
        assert!((m.log_scale.x - (0.02f32).ln()).abs() < 1e-5);
        assert_eq!(m.opacity, 0.8);
        assert_eq!(out.get(5).mean.z, -5.0);
        assert!(out.get(6).mean.x.is_nan());
        // Off (tolerance 0 or NaN) changes nothing.
        assert_eq!(merge_redundant(&set, &camera(), 2, 0.0).len(), set.len());
        assert_eq!(
            merge_redundant(&set, &camera(), 2, f32::NAN).len(),
            set.len()
        );
    }
}
