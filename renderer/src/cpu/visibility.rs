//! How much each Gaussian shows in a view: its blend weight (alpha times transmittance)
//! summed over the view's pixels, in pixels. A Gaussian hidden behind opaque ones, outside
//! the view or too faint to draw sums to 0, so a bin map can drop what none of its views
//! sees. Exactly the gradient of the rendered red channel's sum with respect to each
//! Gaussian's red colour, so it comes from the backward pass that training already checks.

use rayon::prelude::*;

use super::backward::{backward, OutputGrads};
use super::composite::render;
use crate::camera::CameraParams;
use crate::gaussians::SplatsView;
use crate::output::RenderSettings;
use crate::real::Real;

/// Per Gaussian, its blend weights summed over the pixels of `cam`'s image.
pub fn blend_weights<T: Real>(
    splats: &SplatsView<'_, T>,
    cam: &CameraParams<T>,
    settings: &RenderSettings,
) -> Vec<T> {
    let fwd = render(splats, cam, settings);
    let unit_red: Vec<T> = (0..fwd.output.pixels())
        .into_par_iter()
        .flat_map_iter(|_| [T::one(), T::zero(), T::zero()])
        .collect();
    let grads = OutputGrads {
        rgb: Some(&unit_red),
        ..OutputGrads::default()
    };
    backward(splats, cam, settings, &fwd, &grads)
        .colors
        .into_iter()
        .map(|c| c[0])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Camera, Gaussian, GaussianSet, Intrinsics};
    use glam::{Quat, Vec3};

    fn disc(z: f32, x: f32, opacity: f32, scale: f32) -> Gaussian {
        Gaussian {
            mean: Vec3::new(x, 0.0, z),
            log_scale: Vec3::new(scale, scale, 0.01).ln(),
            rotation: Quat::IDENTITY,
            opacity,
            color: Vec3::new(0.3, 0.6, 0.9),
            confidence: 1.0,
        }
    }

    fn weights(gs: &[Gaussian]) -> (Vec<f32>, f32) {
        let mut set = GaussianSet::default();
        gs.iter().for_each(|&g| set.push(g));
        let cam = Camera::identity(Intrinsics::from_hfov(48, 32, 90.0)).params::<f32>();
        let settings = RenderSettings::default();
        let alpha: f32 = render(&set.view().unwrap(), &cam, &settings)
            .output
            .alpha
            .iter()
            .sum();
        (blend_weights(&set.view().unwrap(), &cam, &settings), alpha)
    }

    #[test]
    fn a_lone_gaussian_weighs_its_alpha_and_a_hidden_or_absent_one_nothing() {
        let (w, alpha) = weights(&[disc(5.0, 0.0, 0.8, 0.5)]);
        assert!(
            alpha > 10.0 && (w[0] - alpha).abs() < 1e-3 * alpha,
            "{w:?} {alpha}"
        );
        // Behind a large opaque wall (alpha clamped to 0.99, so 1% of it shows through): under
        // 1.1% of what it weighs in the open.
        let (open, _) = weights(&[disc(6.0, 0.0, 0.9, 0.3)]);
        let (w, _) = weights(&[disc(2.0, 0.0, 1.0, 20.0), disc(6.0, 0.0, 0.9, 0.3)]);
        assert!(
            w[0] > 100.0 && open[0] > 5.0 && w[1] < 0.011 * open[0],
            "{w:?} {open:?}"
        );
        // Behind the camera, far to the side, transparent: 0.
        let (w, _) = weights(&[
            disc(-5.0, 0.0, 0.9, 0.5),
            disc(5.0, 500.0, 0.9, 0.5),
            disc(5.0, 0.0, 0.0, 0.5),
        ]);
        assert_eq!(w, vec![0.0, 0.0, 0.0]);
        // Far, tiny, huge: finite.
        let (w, _) = weights(&[
            disc(1e6, 0.0, 0.9, 1e-6),
            disc(5.0, 0.0, 0.9, 1e6),
            disc(1e-4, 0.0, 0.9, 0.1),
        ]);
        assert!(w.iter().all(|v| v.is_finite() && *v >= 0.0), "{w:?}");
    }
}
