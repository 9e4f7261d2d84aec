//! `sgm_surface`: one hybrid of the classical and the learned matcher. On a near scene the
//! first pair has already been matched by SGM (the fit of `auto_depth_range`, the hints of
//! `sgm_guidance`); wherever that match passed SGM's own checks (uniqueness, left-right
//! consistency, speckle filter), the left view takes SGM's pixel-aligned Gaussians, exactly
//! as `--method sgm` makes them, and the network's Gaussians that this surface already
//! explains (in the left image, not clearly behind it) are dropped. The network keeps
//! everything SGM left: unmatched pixels (weak texture, half-occlusions), surfaces only the
//! right view saw, and the whole of every scene it was not fitted on (streets).
//!
//! Why: the network places Gaussians every `gaussian_stride` pixels with footprints that
//! straddle depth edges, so even where its depth agrees with SGM's its rendered depth bleeds
//! foreground over background; SGM's one-pixel discs do not.

use glam::Vec3;
use renderer::{Camera, Gaussian, GaussianSet};

use super::guidance::SgmHints;
use crate::baseline::unproject::unproject;
use crate::baseline::{DisparityMap, SgmConfig};
use crate::frame::RgbImage;

/// What SGM's confident surface does to the network's Gaussians.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SgmSurface {
    /// Keep the network's Gaussians off SGM's surface: one clearly in front of it at its
    /// own pixel (a floater before a matched wall) is dropped, one whose footprint reaches
    /// over a matched surface behind it (bleeding across a depth edge) shrinks until it
    /// stops short of it; nothing is added.
    Trim,
    /// Drop the network's Gaussians on or in front of SGM's surface within their footprint
    /// and add SGM's own Gaussians of the left view where it matched, exactly as
    /// `--method sgm` makes them.
    Replace,
    /// As `Trim`, and SGM's own Gaussians of the left view added where it matched.
    Join,
}

/// How far from SGM's surface, as a fraction of its depth, a learned Gaussian counts as on
/// it ([`verdict`]). Gaussians further behind (what the right view saw behind a
/// foreground) are always kept.
pub const SURFACE_MARGIN: f32 = 0.1;
/// The footprint tested: this many standard deviations (the largest axis) around the
/// centre, in pixels of the left image.
const FOOTPRINT_SIGMAS: f32 = 2.0;
/// The widest footprint tested, pixels from the centre: bounds the work per Gaussian.
const MAX_RADIUS: i64 = 6;
/// With `Trim`, a Gaussian that would have to shrink below this share of its size is
/// dropped instead.
const MIN_SHRINK: f32 = 0.1;

/// `learned` (the network's bin map) with SGM's surface of the first pair laid in: SGM's
/// Gaussians of the left view (`left` image at the hints' size, seen by `camera`, whose
/// intrinsics are scaled to that size here) replace the learned Gaussians they explain.
/// At most `budget` Gaussians are returned (the most opaque). Returns `learned` unchanged
/// when `left` is not the hints' size or the hints carry no usable rig (`fx_baseline` not
/// finite and positive).
pub fn with_sgm_surface(
    learned: &GaussianSet,
    hints: &SgmHints,
    left: &RgbImage,
    camera: &Camera,
    mode: SgmSurface,
    budget: usize,
) -> GaussianSet {
    let (w, h) = (hints.width, hints.height);
    let sized = (left.width as usize, left.height as usize) == (w, h)
        && hints.disparity.len() == w * h
        && hints.confidence.len() == w * h;
    if !(sized && hints.fx_baseline.is_finite() && hints.fx_baseline > 0.0 && w * h > 0) {
        return learned.clone();
    }
    let camera = Camera {
        intrinsics: camera.intrinsics.scaled(w as u32, h as u32),
        ..*camera
    };
    let baseline = hints.fx_baseline / camera.intrinsics.fx;
    if !(baseline.is_finite() && baseline > 0.0) {
        return learned.clone();
    }
    let map = DisparityMap {
        width: w as u32,
        height: h as u32,
        disparity: hints.disparity.clone(),
        confidence: hints.confidence.clone(),
    };
    let surface = match mode {
        SgmSurface::Replace | SgmSurface::Join => {
            unproject(&map, left, &camera, baseline, &SgmConfig::default())
        }
        SgmSurface::Trim => Vec::new(),
    };
    // SGM's camera depth per pixel (NaN where it matched nothing): the surface the learned
    // Gaussians are tested against.
    let depths: Vec<f32> = hints
        .disparity
        .iter()
        .map(|&d| match d > 0.0 {
            true => hints.fx_baseline / d,
            false => f32::NAN,
        })
        .collect();
    let mut all: Vec<Gaussian> = (0..learned.len())
        .filter_map(
            |i| match verdict(learned, i, &depths, (w, h), &camera, mode) {
                Verdict::Keep => Some(learned.get(i)),
                Verdict::Drop => None,
                Verdict::Shrink(factor) => Some(Gaussian {
                    log_scale: learned.log_scales[i] + Vec3::splat(factor.ln()),
                    ..learned.get(i)
                }),
            },
        )
        .chain(surface)
        .collect();
    if all.len() > budget {
        let mut order: Vec<usize> = (0..all.len()).collect();
        order.sort_by(|&a, &b| all[b].opacity.total_cmp(&all[a].opacity).then(a.cmp(&b)));
        let mut keep = vec![false; all.len()];
        order.into_iter().take(budget).for_each(|i| keep[i] = true);
        let mut flags = keep.into_iter();
        all.retain(|_| flags.next().unwrap_or(false));
    }
    let mut out = GaussianSet::with_capacity(all.len());
    all.into_iter().for_each(|g| out.push(g));
    out
}

/// What SGM's surface does to one learned Gaussian.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Verdict {
    /// Kept as it is.
    Keep,
    /// Dropped.
    Drop,
    /// Kept with its scales multiplied by this factor in (0, 1).
    Shrink(f32),
}

/// What SGM's surface does to learned Gaussian `i`, from the SGM depths (`depths`, NaN: no
/// match) within its footprint in `camera`'s image (`w` x `h`):
/// - `Replace`: dropped when anywhere within its footprint it lies less than
///   [`SURFACE_MARGIN`] behind SGM's surface or in front of it, since SGM's discs draw
///   those pixels.
/// - `Trim`: only SGM pixels it lies clearly in front of count (nearer than the surface by
///   more than the margin). On its own pixel it is a floater before a matched surface and
///   is dropped; elsewhere in its footprint it would bleed over that surface (a depth
///   edge), so it shrinks until its footprint stops short of the nearest such pixel.
fn verdict(
    set: &GaussianSet,
    i: usize,
    depths: &[f32],
    (w, h): (usize, usize),
    camera: &Camera,
    mode: SgmSurface,
) -> Verdict {
    let p = camera.rotation * (set.means[i] - camera.position);
    if !(p.is_finite() && p.z > 1e-6) {
        return Verdict::Keep;
    }
    let k = camera.intrinsics;
    let (u, v) = (k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy);
    // The middle of the three axes: a disc's smaller in-plane radius, and for a Gaussian
    // drawn out along its ray, its width across the ray.
    let mut axes = set.log_scales[i].to_array();
    axes.sort_by(f32::total_cmp);
    let reach = FOOTPRINT_SIGMAS * axes[1].exp() * k.fx / p.z;
    let radius = match reach.ceil() {
        r if r.is_finite() => (r as i64).clamp(0, MAX_RADIUS),
        _ => MAX_RADIUS,
    };
    let (cu, cv) = (u.round() as i64, v.round() as i64);
    // SGM's depth `s` at a pixel counts when `s` exceeds this.
    let limit = match mode {
        SgmSurface::Replace => p.z / (1.0 + SURFACE_MARGIN),
        SgmSurface::Trim | SgmSurface::Join => p.z * (1.0 + SURFACE_MARGIN),
    };
    // The distance from the projected centre to the nearest pixel that counts.
    let mut nearest = f32::INFINITY;
    for y in (cv - radius).max(0)..=(cv + radius).min(h as i64 - 1) {
        for x in (cu - radius).max(0)..=(cu + radius).min(w as i64 - 1) {
            // A NaN depth (no match) fails the comparison.
            if depths[y as usize * w + x as usize] > limit {
                let d = (x as f32 - u).hypot(y as f32 - v);
                nearest = nearest.min(d);
            }
        }
    }
    match mode {
        _ if !nearest.is_finite() => Verdict::Keep,
        SgmSurface::Replace => Verdict::Drop,
        // The pixel's own half-width lies between its centre and the footprint's edge.
        SgmSurface::Trim | SgmSurface::Join => match (nearest - 0.5) / reach {
            f if f >= 1.0 || !f.is_finite() => Verdict::Keep,
            f if f < MIN_SHRINK => Verdict::Drop,
            f => Verdict::Shrink(f),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::geometry::test_camera;
    use glam::Quat;

    /// SGM's hints for a `w` x `h` view whose left half matched a wall at `disparity` px.
    fn half_wall(w: usize, h: usize, disparity: f32, fx_baseline: f32) -> SgmHints {
        let left_half = |i: usize| i % w < w / 2;
        SgmHints {
            disparity: (0..w * h)
                .map(|i| if left_half(i) { disparity } else { f32::NAN })
                .collect(),
            confidence: (0..w * h)
                .map(|i| if left_half(i) { 1.0 } else { 0.0 })
                .collect(),
            width: w,
            height: h,
            fx_baseline,
        }
    }

    fn grey(w: usize, h: usize) -> RgbImage {
        RgbImage {
            width: w as u32,
            height: h as u32,
            data: vec![0.5; w * h * 3],
        }
    }

    fn at(mean: Vec3) -> Gaussian {
        Gaussian {
            mean,
            log_scale: Vec3::splat(-3.0),
            rotation: Quat::IDENTITY,
            opacity: 0.9,
            color: Vec3::ONE,
            confidence: 1.0,
        }
    }

    #[test]
    fn sgm_replaces_what_it_matched_and_the_network_keeps_the_rest() {
        // test_camera: 80x40, fx 100, looking down +z. fx * b = 100 * 0.5 = 50, so a
        // disparity of 5 px is a wall at 10 m.
        let camera = test_camera(0.0);
        let k = camera.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let hints = half_wall(w, h, 5.0, 50.0);
        let ray =
            |x: f32, y: f32, z: f32| Vec3::new((x - k.cx) / k.fx * z, (y - k.cy) / k.fy * z, z);
        let mut learned = GaussianSet::with_capacity(4);
        learned.push(at(ray(10.0, 20.0, 10.2))); // on SGM's wall: replaced
        learned.push(at(ray(10.0, 20.0, 4.0))); // a floater in front of it: replaced
        learned.push(at(ray(10.0, 20.0, 14.0))); // 40% behind it: kept
        learned.push(at(ray(60.0, 20.0, 10.0))); // where SGM matched nothing: kept
                                                 // At 5 m its 5 cm deviation spans 1 px, so 2 sigma reach 2 px from the centre: at
                                                 // pixel 41 that covers SGM's wall at pixel 39 (dropped: it would bleed over it); at
                                                 // pixel 44 it stays on unmatched pixels (kept).
        learned.push(at(ray(41.0, 20.0, 5.0)));
        learned.push(at(ray(44.0, 20.0, 5.0)));
        let out = with_sgm_surface(
            &learned,
            &hints,
            &grey(w, h),
            &camera,
            SgmSurface::Replace,
            usize::MAX,
        );
        let sgm_count = (w / 2) * h;
        assert_eq!(out.len(), 3 + sgm_count);
        assert!((out.means[0].z - 14.0).abs() < 1e-4);
        assert!((out.means[1].z - 10.0).abs() < 1e-4);
        assert!((out.means[2].x - ray(44.0, 20.0, 5.0).x).abs() < 1e-5);
        for z in out.means[3..].iter().map(|m| m.z) {
            assert!((z - 10.0).abs() < 1e-3, "SGM's Gaussian at {z} m");
        }
        // Trimmed: the floater goes, the one bleeding over the wall shrinks until its 2
        // sigma (2 e^-3 m at 5 m, fx 100) stop half a pixel short of pixel 39, 2 px away;
        // the rest stay as they are, nothing is added.
        let trimmed = with_sgm_surface(
            &learned,
            &hints,
            &grey(w, h),
            &camera,
            SgmSurface::Trim,
            usize::MAX,
        );
        let kept = [0, 2, 3, 4, 5].map(|i| learned.means[i]);
        assert_eq!(trimmed.means, kept);
        let shrunk = trimmed.log_scales[3] - learned.log_scales[4];
        let factor = 1.5 / (2.0 * (-3f32).exp() * 100.0 / 5.0);
        assert!((shrunk - Vec3::splat(factor.ln())).abs().max_element() < 1e-4);
        assert_eq!(trimmed.log_scales[4], learned.log_scales[5]);
    }

    #[test]
    fn the_budget_keeps_the_most_opaque() {
        let camera = test_camera(0.0);
        let (w, h) = (
            camera.intrinsics.width as usize,
            camera.intrinsics.height as usize,
        );
        let mut learned = GaussianSet::with_capacity(1);
        let mut faint = at(Vec3::new(1.0, 0.0, 10.0));
        faint.opacity = 0.01;
        learned.push(faint);
        let hints = half_wall(w, h, 5.0, 50.0);
        let out = with_sgm_surface(
            &learned,
            &hints,
            &grey(w, h),
            &camera,
            SgmSurface::Replace,
            100,
        );
        assert_eq!(out.len(), 100);
        assert!(out.opacities.iter().all(|&o| o > 0.01));
        assert!(with_sgm_surface(
            &learned,
            &hints,
            &grey(w, h),
            &camera,
            SgmSurface::Replace,
            0
        )
        .is_empty());
    }

    #[test]
    fn hints_of_another_size_or_without_a_rig_leave_the_network_alone() {
        let camera = test_camera(0.0);
        let (w, h) = (
            camera.intrinsics.width as usize,
            camera.intrinsics.height as usize,
        );
        let mut learned = GaussianSet::with_capacity(1);
        learned.push(at(Vec3::new(0.0, 0.0, 10.0)));
        for hints in [
            half_wall(w, h, 5.0, 0.0),
            half_wall(w, h, 5.0, f32::NAN),
            half_wall(w, h, 5.0, f32::INFINITY),
            half_wall(w / 2, h, 5.0, 50.0),
        ] {
            let out = with_sgm_surface(
                &learned,
                &hints,
                &grey(w, h),
                &camera,
                SgmSurface::Replace,
                usize::MAX,
            );
            assert_eq!(out.means, learned.means);
        }
        let empty = SgmHints {
            disparity: vec![],
            confidence: vec![],
            width: 0,
            height: 0,
            fx_baseline: 50.0,
        };
        let out = with_sgm_surface(
            &learned,
            &empty,
            &grey(0, 0),
            &camera,
            SgmSurface::Replace,
            usize::MAX,
        );
        assert_eq!(out.len(), 1);
    }

    #[test]
    fn extreme_disparities_give_finite_gaussians_or_none() {
        let camera = test_camera(0.0);
        let k = camera.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let learned = GaussianSet::with_capacity(0);
        for d in [1e-30, 1e-6, 0.5, 1e6, 1e30, f32::INFINITY, -3.0] {
            let out = with_sgm_surface(
                &learned,
                &half_wall(w, h, d, 50.0),
                &grey(w, h),
                &camera,
                SgmSurface::Replace,
                usize::MAX,
            );
            for i in 0..out.len() {
                let g = out.get(i);
                assert!(
                    g.mean.is_finite() && g.log_scale.is_finite(),
                    "d {d}: {g:?}"
                );
            }
        }
    }
}
