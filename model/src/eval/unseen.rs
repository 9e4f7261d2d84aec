//! Where a method must pay for what the input did not show: the target pixels whose true
//! surface point no input view saw, and the PSNR on those pixels alone ("unseen-region PSNR").
//! A point counts as seen by an input view when it lies in front of it, projects inside its
//! image, and is not hidden there: its depth in that view is at most [`OCCLUSION_TOLERANCE`]
//! beyond the view's own exact depth at that pixel. Needs exact depth for the targets and the
//! inputs, which generated drives have ([`crate::kitti360::exact_depth`]); real data has none
//! and gets no score.

use glam::Vec3;
use renderer::Camera;

use crate::frame::{DepthMap, RgbImage};
use crate::metrics::{psnr_masked, MetricError};

/// Relative depth beyond an input view's own surface at which a point counts as occluded in
/// that view (5%: about the exact depth's rounding and a pixel's footprint on slanted
/// surfaces at these resolutions, well under the gap behind a car or a pole).
pub const OCCLUSION_TOLERANCE: f32 = 0.05;

/// Fewest unseen pixels (and at least this fraction of the image, 1/200) a frame needs for
/// an unseen-region PSNR; below that it has none (`None`), so a handful of edge pixels
/// does not swing the average.
pub const MIN_UNSEEN_PIXELS: usize = 16;

/// One input view: its camera and exact depth, in the same frame as the target camera.
#[derive(Clone, Copy, Debug)]
pub struct InputView<'a> {
    /// The view's camera.
    pub camera: &'a Camera,
    /// Its exact z-depth (0: sky or unknown).
    pub depth: &'a DepthMap,
}

/// Per target pixel (row major), whether its true surface point went unseen by every input
/// view. Pixels without a surface (depth 0, the sky) are never unseen: there is no point to
/// have missed. A depth map not of the target camera's size marks nothing.
pub fn unseen_mask(target: &Camera, depth: &DepthMap, inputs: &[InputView]) -> Vec<bool> {
    let k = &target.intrinsics;
    let n = depth.data.len();
    if (depth.width, depth.height) != (k.width, k.height) {
        return vec![false; n];
    }
    let to_world = target.rotation.transpose();
    (0..n)
        .map(|i| {
            let d = depth.data[i];
            if !(d > 0.0 && d.is_finite()) {
                return false;
            }
            let (x, y) = ((i % k.width as usize) as f32, (i / k.width as usize) as f32);
            let local = Vec3::new((x - k.cx) / k.fx * d, (y - k.cy) / k.fy * d, d);
            let point = to_world * local + target.position;
            !inputs.iter().any(|view| sees(view, point))
        })
        .collect()
}

/// Whether `view` sees `point` (same frame): in front, inside, not hidden.
fn sees(view: &InputView, point: Vec3) -> bool {
    let k = &view.camera.intrinsics;
    let p = view.camera.rotation * (point - view.camera.position);
    if p.z <= 1e-3 {
        return false;
    }
    let (u, v) = (
        (k.fx * p.x / p.z + k.cx).round(),
        (k.fy * p.y / p.z + k.cy).round(),
    );
    if !(u >= 0.0 && v >= 0.0 && u < k.width as f32 && v < k.height as f32) {
        return false;
    }
    if (view.depth.width, view.depth.height) != (k.width, k.height) {
        return false;
    }
    let surface = view.depth.data[v as usize * k.width as usize + u as usize];
    // Sky at that pixel while the point is a surface: a depth edge, nothing in front of it.
    surface <= 0.0 || p.z <= surface * (1.0 + OCCLUSION_TOLERANCE)
}

/// PSNR of `render` against `truth` on the `unseen` pixels only, or `None` when fewer than
/// [`MIN_UNSEEN_PIXELS`] (or 1/200 of the image) are unseen.
pub fn unseen_psnr(
    render: &RgbImage,
    truth: &RgbImage,
    unseen: &[bool],
) -> Result<Option<f64>, MetricError> {
    let count = unseen.iter().filter(|&&u| u).count();
    if count < MIN_UNSEEN_PIXELS.max(unseen.len() / 200) {
        return Ok(None);
    }
    psnr_masked(render, truth, unseen).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;
    use renderer::Intrinsics;

    const W: u32 = 40;
    const H: u32 = 20;

    fn camera_at(x: f32) -> Camera {
        let mut c = Camera::identity(Intrinsics::from_hfov(W, H, 90.0));
        c.position = Vec3::new(x, 0.0, 0.0);
        c
    }

    fn flat(depth: f32) -> DepthMap {
        DepthMap {
            width: W,
            height: H,
            data: vec![depth; (W * H) as usize],
        }
    }

    #[test]
    fn a_wall_seen_by_the_input_is_seen_and_what_lies_outside_it_is_not() {
        let target = camera_at(0.0);
        let wall = flat(10.0);
        let same = InputView {
            camera: &target,
            depth: &wall,
        };
        assert!(unseen_mask(&target, &wall, &[same]).iter().all(|u| !u));
        // An input 20 m to the left, looking the same way: its 90-degree view of a wall 10 m
        // away spans x in [-30, -10], so no target pixel (x in [-10, 10]) is inside it.
        let far_left = camera_at(-20.0);
        let input = InputView {
            camera: &far_left,
            depth: &wall,
        };
        let mask = unseen_mask(&target, &wall, &[input]);
        assert!(mask.iter().all(|&u| u));
        // Half a field of view to the left: the target's left half is seen, the right is not.
        let half = camera_at(-5.0);
        let input = InputView {
            camera: &half,
            depth: &wall,
        };
        let mask = unseen_mask(&target, &wall, &[input]);
        let row: Vec<bool> = mask[..W as usize].to_vec();
        assert!(!row[2] && row[W as usize - 3], "{row:?}");
        let unseen = mask.iter().filter(|&&u| u).count() as f32 / mask.len() as f32;
        assert!((unseen - 0.25).abs() < 0.05, "{unseen}");
    }

    #[test]
    fn an_occluder_in_the_input_hides_the_wall_behind_it() {
        let target = camera_at(0.0);
        let wall = flat(10.0);
        // The input stands where the target does but sees a screen at 4 m everywhere.
        let screen = flat(4.0);
        let input = InputView {
            camera: &target,
            depth: &screen,
        };
        assert!(unseen_mask(&target, &wall, &[input]).iter().all(|&u| u));
        // Within the tolerance it is the same surface.
        let close = flat(10.0 / (1.0 + OCCLUSION_TOLERANCE) + 0.01);
        let input = InputView {
            camera: &target,
            depth: &close,
        };
        assert!(unseen_mask(&target, &wall, &[input]).iter().all(|&u| !u));
        // Sky in the target is never unseen; a surface with no input view at all is.
        assert!(unseen_mask(&target, &flat(0.0), &[]).iter().all(|&u| !u));
        assert!(unseen_mask(&target, &wall, &[]).iter().all(|&u| u));
    }

    #[test]
    fn extremes_give_masks_not_panics() {
        let target = camera_at(0.0);
        let mut odd = flat(10.0);
        odd.data[0] = f32::NAN;
        odd.data[1] = f32::INFINITY;
        odd.data[2] = 1e-7;
        odd.data[3] = 1e30;
        let far = {
            let mut c = camera_at(0.0);
            c.position = Vec3::new(1e5, -1e5, 3.0);
            c
        };
        let wrong_size = DepthMap::empty(3, 3);
        for input in [&far, &target] {
            for depth in [&odd, &wrong_size] {
                let view = InputView {
                    camera: input,
                    depth,
                };
                let mask = unseen_mask(&target, &odd, &[view]);
                assert_eq!(mask.len(), odd.data.len());
                assert!(!mask[0] && !mask[1]);
            }
        }
        assert_eq!(unseen_mask(&target, &wrong_size, &[]), vec![false; 9]);
    }

    #[test]
    fn unseen_psnr_scores_only_the_masked_pixels_and_needs_enough_of_them() {
        let image = |v: f32| RgbImage {
            width: W,
            height: H,
            data: vec![v; (3 * W * H) as usize],
        };
        let (truth, mut render) = (image(0.5), image(0.5));
        // Unseen pixels are off by 0.1 (20 dB); seen ones are exact.
        let mask: Vec<bool> = (0..W * H).map(|i| i % 4 == 0).collect();
        for (i, &m) in mask.iter().enumerate() {
            if m {
                render.data[3 * i..3 * i + 3].fill(0.6);
            }
        }
        let got = unseen_psnr(&render, &truth, &mask).unwrap().unwrap();
        assert!((got - 20.0).abs() < 1e-4, "{got}");
        let few: Vec<bool> = (0..W * H).map(|i| i < 3).collect();
        assert_eq!(unseen_psnr(&render, &truth, &few).unwrap(), None);
    }
}
