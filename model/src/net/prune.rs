//! Dropping the Gaussians that no input view sees: hidden behind nearer ones (the right
//! view's copy of a surface the left view already covers, points predicted inside objects),
//! outside every image, or too faint to draw. Each Gaussian's blend weight is summed over
//! the input views ([`renderer::cpu::blend_weights`], in pixels); below the threshold it
//! goes. Views the bin never had (later frames, novel views) are not consulted, so pruning
//! trades their quality for count: measured by `stereosplat bench pareto`'s `min_view_weight`
//! point (docs/evaluation.md, "Speed against accuracy: `bench pareto`").

use renderer::cpu::blend_weights;
use renderer::{Camera, GaussianSet, RenderSettings};

/// The Gaussians of `set` whose blend weight summed over `cameras` reaches `min_weight`
/// pixels, in their order. A set that does not form a valid view (mismatched arrays) is
/// returned unchanged.
pub fn prune_unseen(set: &GaussianSet, cameras: &[Camera], min_weight: f32) -> GaussianSet {
    let Ok(view) = set.view() else {
        return set.clone();
    };
    let settings = RenderSettings::default();
    let mut total = vec![0.0f32; set.len()];
    for cam in cameras {
        let weights = blend_weights(&view, &cam.params::<f32>(), &settings);
        for (t, w) in total.iter_mut().zip(weights) {
            *t += w;
        }
    }
    let mut out = GaussianSet::with_capacity(set.len());
    for (i, &w) in total.iter().enumerate() {
        if w >= min_weight {
            out.push(set.get(i));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};
    use renderer::{Gaussian, Intrinsics};

    fn disc(x: f32, z: f32, opacity: f32, scale: f32) -> Gaussian {
        Gaussian {
            mean: Vec3::new(x, 0.0, z),
            log_scale: Vec3::new(scale, scale, 0.01).ln(),
            rotation: Quat::IDENTITY,
            opacity,
            color: Vec3::splat(0.5),
            confidence: 0.9,
        }
    }

    #[test]
    fn hidden_and_absent_gaussians_go_and_a_second_view_can_keep_one() {
        let k = Intrinsics::from_hfov(48, 32, 90.0);
        let left = Camera::identity(k);
        let mut set = GaussianSet::default();
        for g in [
            disc(0.0, 2.0, 1.0, 1.0),  // a wall in front of the left camera
            disc(0.0, 6.0, 0.9, 0.3),  // behind it
            disc(50.0, 5.0, 0.9, 0.3), // outside the image
            disc(0.0, -3.0, 0.9, 0.3), // behind the camera
            disc(1.5, 4.0, 0.9, 0.3),  // beside the wall, in the open
        ] {
            set.push(g);
        }
        let kept = prune_unseen(&set, &[left], 0.5);
        assert_eq!(kept.means, vec![set.means[0], set.means[4]]);
        // A camera 3 m to the left, turned back towards the hidden disc, sees it past the
        // wall's edge.
        let mut side = Camera::identity(k);
        side.position = Vec3::new(-4.0, 0.0, 6.0);
        side.rotation = glam::Mat3::from_rotation_y(std::f32::consts::FRAC_PI_2).transpose();
        let kept = prune_unseen(&set, &[left, side], 0.5);
        assert!(kept.means.contains(&set.means[1]), "{:?}", kept.means);
        assert!(prune_unseen(&GaussianSet::default(), &[left], 0.5).is_empty());
        assert_eq!(prune_unseen(&set, &[], 0.0).len(), set.len());
    }
}
