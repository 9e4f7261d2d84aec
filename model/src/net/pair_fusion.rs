//! Fusion of the Gaussians of several input pairs by visibility: the first pair is the anchor
//! and each later pair adds only what the pairs before it do not already explain.
//!
//! Every view predicts one Gaussian per pixel, so two pairs that see the same surface put two
//! layers of Gaussians on it, each placed by its own depth estimate. The network's opacity is
//! trained for one layer per surface; a second, slightly misplaced layer in front of the first
//! darkens and blurs the render and pulls its depth (with the bin's first three pairs as
//! input, unfused, the first frame loses PSNR and bin-average AbsRel rises:
//! `model/tests/integration/pair_fusion.rs` prints both on a generated drive, `bash
//! scripts/eval_tiny.sh` on the held-out drives, `results/stereosplat_tiny/`). A Gaussian of a
//! later pair is dropped when it lies inside the image of an earlier view and not clearly
//! behind that view's estimated surface: the earlier view already has a Gaussian there, or has
//! seen free space there. What only the later pairs see (regions outside the earlier views,
//! surfaces hidden behind the earlier views' foreground) is kept. The left and right view of
//! one pair are never tested against each other: the network was trained on both layers
//! together. Pairs come in input order, so the real first pair outranks later real or pseudo
//! pairs.

use glam::DVec3;
use renderer::Camera;

/// A fusion rule ([`surviving`], [`unexplained`]): centres, the views' estimated depths on
/// their grids, the views' cameras, the grid, its stride, the margin; a flag per centre.
pub type Rule = fn(&[f32], &[f32], &[Camera], (usize, usize), usize, f32) -> Vec<bool>;

/// Which Gaussians survive the fusion. `means` holds 3 values per Gaussian (bin frame), one
/// Gaussian per pixel of an `hg` x `wg` grid with `stride` per view, view-major, views in
/// pairs (left, right, left, ...) as `cameras`; `depths` holds each view's estimated camera
/// depth on the same grid. A Gaussian of pair `k` survives unless some view of pairs `0..k`
/// sees it at a camera depth below `(1 + margin)` times that view's depth at the pixel it
/// projects to. Gaussians with non-finite positions survive here (the pruning drops them).
pub fn surviving(
    means: &[f32],
    depths: &[f32],
    cameras: &[Camera],
    (hg, wg): (usize, usize),
    stride: usize,
    margin: f32,
) -> Vec<bool> {
    let per_view = hg * wg;
    kept(means, depths, cameras, (hg, wg), stride, margin, |i| {
        2 * (i / per_view / 2)
    })
}

/// Which of `points` (3 values each, bin frame; Gaussians of no view, such as the volume
/// branch's) no view explains: each is tested against every view of `cameras`, whose
/// estimated depths on its `hg` x `wg` grid (view-major) are `depths`, with `margin` as in
/// [`surviving`]. Non-finite points survive here (the pruning drops them).
pub fn unexplained(
    points: &[f32],
    depths: &[f32],
    cameras: &[Camera],
    grid: (usize, usize),
    stride: usize,
    margin: f32,
) -> Vec<bool> {
    kept(points, depths, cameras, grid, stride, margin, |_| {
        cameras.len()
    })
}

/// Which of `points` no view before `views_before(i)` (for point `i`) explains.
fn kept(
    points: &[f32],
    depths: &[f32],
    cameras: &[Camera],
    (hg, wg): (usize, usize),
    stride: usize,
    margin: f32,
    views_before: impl Fn(usize) -> usize,
) -> Vec<bool> {
    let per_view = hg * wg;
    points
        .chunks_exact(3)
        .enumerate()
        .map(|(i, p)| {
            let mean = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            !(0..views_before(i)).any(|view| {
                explained(
                    mean,
                    &cameras[view],
                    &depths[view * per_view..(view + 1) * per_view],
                    (hg, wg),
                    stride,
                    margin,
                )
            })
        })
        .collect()
}

/// Whether `camera`, whose estimated depths on its Gaussian grid are `depths`, sees `mean`
/// in its image and not clearly behind its surface.
fn explained(
    mean: DVec3,
    camera: &Camera,
    depths: &[f32],
    (hg, wg): (usize, usize),
    stride: usize,
    margin: f32,
) -> bool {
    let p = camera.rotation.as_dmat3() * (mean - camera.position.as_dvec3());
    if p.z.is_nan() || p.z <= 1e-6 {
        return false;
    }
    let k = camera.intrinsics;
    let s = stride as f64;
    let gx = ((k.fx as f64 * p.x / p.z + k.cx as f64) / s).round();
    let gy = ((k.fy as f64 * p.y / p.z + k.cy as f64) / s).round();
    if !(gx >= 0.0 && gy >= 0.0 && gx < wg as f64 && gy < hg as f64) {
        return false;
    }
    let surface = depths[gy as usize * wg + gx as usize] as f64;
    surface.is_finite() && p.z < surface * (1.0 + margin as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::geometry::test_camera;

    /// Two pairs looking down +z (80x40, fx 100, 0.5 m baseline), the second 1 m ahead.
    fn cameras() -> Vec<Camera> {
        let ahead = |x: f32| {
            let mut c = test_camera(x);
            c.position.z = 1.0;
            c
        };
        vec![test_camera(0.0), test_camera(0.5), ahead(0.0), ahead(0.5)]
    }

    #[test]
    fn points_of_no_view_survive_only_where_no_view_explains_them() {
        let cams = cameras();
        let (hg, wg, stride) = (2, 4, 20);
        let depths = vec![10.0f32; 4 * hg * wg];
        // On the wall of view 0, in front of it, 50% behind it, beside every view, behind
        // the cameras, NaN.
        let points = [
            0.0,
            0.0,
            10.0,
            0.0,
            0.0,
            4.0,
            0.0,
            0.0,
            16.0,
            500.0,
            0.0,
            10.0,
            0.0,
            0.0,
            -5.0,
            f32::NAN,
            0.0,
            0.0,
        ];
        let kept = unexplained(&points, &depths, &cams, (hg, wg), stride, 0.1);
        assert_eq!(kept, [false, false, true, true, true, true]);
        // No view: every point survives.
        assert!(unexplained(&points, &[], &[], (hg, wg), stride, 0.1)
            .iter()
            .all(|k| *k));
    }

    #[test]
    fn later_pairs_keep_only_what_earlier_views_do_not_explain() {
        let cams = cameras();
        let (hg, wg, stride) = (2, 4, 20);
        // Every view sees a wall 10 m from its camera.
        let depths = vec![10.0f32; 4 * hg * wg];
        let mut means = vec![0f32; 3 * 4 * hg * wg];
        // Pair 1's first Gaussians (view 2, pixels 0..3): on the wall (z = 10 in the bin
        // frame: 10 m from view 0), in front of it, behind it, and far to the side.
        let at = |means: &mut Vec<f32>, i: usize, p: [f32; 3]| {
            means[3 * i..3 * i + 3].copy_from_slice(&p)
        };
        let first = 2 * hg * wg;
        at(&mut means, first, [0.0, 0.0, 10.0]);
        at(&mut means, first + 1, [0.0, 0.0, 5.0]);
        at(&mut means, first + 2, [0.0, 0.0, 14.0]);
        at(&mut means, first + 3, [50.0, 0.0, 10.0]);
        let keep = surviving(&means, &depths, &cams, (hg, wg), stride, 0.1);
        // The anchor pair keeps everything, whatever its positions.
        assert!(keep[..first].iter().all(|&k| k));
        assert_eq!(&keep[first..first + 4], &[false, false, true, true]);
    }

    #[test]
    fn behind_a_camera_or_off_its_image_is_never_explained() {
        let cam = test_camera(0.0);
        let depths = vec![10.0f32; 8];
        let sees =
            |x: f64, y: f64, z: f64| explained(DVec3::new(x, y, z), &cam, &depths, (2, 4), 20, 0.1);
        assert!(!sees(0.0, 0.0, -5.0), "behind the camera");
        assert!(!sees(0.0, 30.0, 1.0), "below the image");
        assert!(!sees(f64::NAN, 0.0, 5.0), "not a position");
        assert!(sees(0.0, 0.0, 10.9), "within the margin behind the surface");
        assert!(!sees(0.0, 0.0, 11.1), "beyond the margin");
    }
}
