//! `auto_depth_range`: the depth candidates spent on the depths the pair shows. The
//! presets spread their candidates from 1 to 100 m, uniform in inverse depth, which suits a
//! street seen from a car's 60 cm rig; an indoor pair at 2-8 m from a 10 cm rig then falls on
//! a handful of candidates 4 px apart (Aloe at its working size), too coarse for matching to
//! place it. Here SGM, on the first pair, measures the disparities the scene holds, and the
//! candidates span them (with a margin) inside the preset's range, never beyond it.

use candle_core::Tensor;
use renderer::Camera;

use super::config::RIG_DEPTH_LIMITS;
use super::guidance::SgmHints;
use super::Config;
use crate::baseline::{rectified_baseline, SgmConfig, SgmReconstructor};
use crate::frame::RgbImage;
use crate::reconstruct::StereoView;

/// Share of the first view's pixels SGM must match for its range to be trusted.
const MIN_MATCHED: f64 = 0.05;
/// Percentiles of the matched disparities taken as the scene's far and near ends, so a few
/// wrong matches cannot stretch the range.
const PERCENTILES: (f64, f64) = (0.02, 0.98);
/// The range is widened by this factor in disparity at both ends.
const MARGIN: f32 = 1.25;
/// The narrowest range kept, as far / near: so few candidates never crowd on one depth.
const MIN_RATIO: f32 = 3.0;
/// A depth range in metres, `0 < near < far`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DepthRange {
    /// Nearest candidate depth.
    pub near: f32,
    /// Farthest candidate depth.
    pub far: f32,
}

/// What SGM on the first pair found: the depth range to use (`None`: the preset's) and its
/// disparities, the hints of `sgm_guidance`.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneFit {
    /// The fitted range; `None` when anything is not finite or the fitted far end is at or
    /// beyond `preset.auto_depth_range_max_far`.
    pub range: Option<DepthRange>,
    /// SGM's disparities of the first pair at the fit's size.
    pub hints: SgmHints,
}

/// SGM on the first pair of `images` `(2K, 3, H, W)` in `[0, 1]` (left, right, ...) with
/// its `cameras`: its disparities, and the range of the scene they span inside `preset`'s
/// `[near, far]` (`None`, keep the preset's, when anything is not finite or the fitted far
/// end is at or beyond `preset.auto_depth_range_max_far`). `None` when the pair is not
/// rectified or SGM matches less than 5% of it.
pub fn fit_scene(images: &Tensor, cameras: &[Camera], preset: &Config) -> Option<SceneFit> {
    // At the network's own input size: matched with its rows averaged in groups of 4 (a
    // quarter of SGM's work), the validation desks' AbsRel was 0.34 against 0.20 at full
    // rows (`results/setting_choices/`).
    let pair = images.narrow(0, 0, 2).ok()?;
    let (left, right) = (pair_image(&pair, 0)?, pair_image(&pair, 1)?);
    let at_image_size = |camera: &Camera| Camera {
        intrinsics: camera.intrinsics.scaled(left.width, left.height),
        ..*camera
    };
    let view = StereoView {
        left: &left,
        right: &right,
        left_camera: at_image_size(cameras.first()?),
        right_camera: at_image_size(cameras.get(1)?),
    };
    let baseline = rectified_baseline(&view).ok()?;
    let sgm = SgmReconstructor::new(SgmConfig {
        min_depth: preset.near,
        ..SgmConfig::default()
    });
    let map = sgm.view_disparity(&view).ok()?;
    let mut matched: Vec<f32> = map
        .disparity
        .iter()
        .copied()
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if (matched.len() as f64) < MIN_MATCHED * map.disparity.len() as f64 {
        return None;
    }
    matched.sort_by(f32::total_cmp);
    let at = |q: f64| matched[((matched.len() - 1) as f64 * q).round() as usize];
    let fb = view.left_camera.intrinsics.fx * baseline;
    let (low, high) = (at(PERCENTILES.0) / MARGIN, at(PERCENTILES.1) * MARGIN);
    let far = fb / low.max(f32::MIN_POSITIVE);
    // A NaN bound fits nothing: only a far end known to be below it passes.
    let within = |max: f32| far.partial_cmp(&max) == Some(std::cmp::Ordering::Less);
    let gated = preset
        .auto_depth_range_max_far
        .is_some_and(|max| !within(max));
    Some(SceneFit {
        range: (!gated)
            .then(|| range_within(fb / high, far, preset))
            .flatten(),
        hints: SgmHints {
            width: map.width as usize,
            height: map.height as usize,
            disparity: map.disparity,
            fx_baseline: fb,
        },
    })
}

/// The candidate range the rig of `cameras` (the first pair: left, right) calls for with
/// `rig_disparity_fraction` set: nearest at the depth whose disparity is that fraction of
/// the width, farthest `far / near` times deeper, within [`RIG_DEPTH_LIMITS`]. `None`: the
/// setting is off, or the first pair is not a usable rig (fewer than two cameras, a
/// baseline that is zero or not finite), where the preset's metres stay.
pub fn rig_range(cameras: &[Camera], cfg: &Config) -> Option<DepthRange> {
    let fraction = cfg.rig_disparity_fraction?;
    let (left, right) = (cameras.first()?, cameras.get(1)?);
    let k = left.intrinsics;
    let baseline = significant_digits((right.position - left.position).length(), 4);
    let near = k.fx * baseline / (fraction * k.width as f32);
    if !(near.is_finite() && near > 0.0 && cfg.far > cfg.near && cfg.near > 0.0) {
        return None;
    }
    let (lo, hi) = RIG_DEPTH_LIMITS;
    let span = cfg.far / cfg.near;
    let near = near.clamp(lo, hi / span);
    Some(DepthRange {
        near,
        far: near * span,
    })
}

/// `x` rounded to `digits` significant digits (itself when not finite and positive). The
/// rig's baseline comes from camera positions, whose last float digits change with where
/// the rig lies in the bin's frame (a float keeps about 7 digits); the candidates
/// must follow the rig, not that noise, and 4 digits (0.1 mm of a 60 cm rig) are finer than
/// any calibration.
fn significant_digits(x: f32, digits: i32) -> f32 {
    if !(x.is_finite() && x > 0.0) {
        return x;
    }
    let scale = 10f64.powi(digits - 1 - (x as f64).log10().floor() as i32);
    ((x as f64 * scale).round() / scale) as f32
}

/// `[near, far]` clamped into the preset's range and widened about its geometric mean to
/// at least [`MIN_RATIO`]; `None` when not finite.
fn range_within(near: f32, far: f32, preset: &Config) -> Option<DepthRange> {
    if !(near.is_finite() && far.is_finite() && near > 0.0) {
        return None;
    }
    let (mut near, mut far) = (near.max(preset.near), far.min(preset.far));
    if far < near * MIN_RATIO {
        let centre = (near * far.max(near)).sqrt();
        near = (centre / MIN_RATIO.sqrt()).max(preset.near);
        far = (near * MIN_RATIO).min(preset.far);
        near = near.min(far / MIN_RATIO).max(preset.near);
    }
    (near < far).then_some(DepthRange { near, far })
}

/// View `index` of `images` `(V, 3, H, W)` as an [`RgbImage`].
fn pair_image(images: &Tensor, index: usize) -> Option<RgbImage> {
    let (_, _, h, w) = images.dims4().ok()?;
    let data = images
        .get(index)
        .and_then(|t| t.permute((1, 2, 0))?.flatten_all()?.to_vec1::<f32>())
        .ok()?;
    Some(RgbImage {
        width: w as u32,
        height: h as u32,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    /// The fitted range alone.
    fn scene_range(images: &Tensor, cameras: &[Camera], preset: &Config) -> Option<DepthRange> {
        fit_scene(images, cameras, preset)?.range
    }

    /// A textured left image and its right image for a plane at disparity `shift` px.
    fn plane_pair(w: usize, h: usize, shift: usize) -> Tensor {
        let left: Vec<f32> = (0..h * w)
            .map(|p| (((p * 2654435761usize) >> 9) % 251) as f32 / 251.0)
            .collect();
        let right: Vec<f32> = (0..h * w)
            .map(|p| left[p - p % w + (p % w + shift).min(w - 1)])
            .collect();
        let planes = |v: &Vec<f32>| Tensor::from_vec(v.repeat(3), (1, 3, h, w), &Device::Cpu);
        Tensor::cat(&[planes(&left).unwrap(), planes(&right).unwrap()], 0).unwrap()
    }

    fn rig(w: u32, h: u32, baseline: f32) -> Vec<Camera> {
        let k = renderer::Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: w as f32 / 2.0,
            cy: h as f32 / 2.0,
            width: w,
            height: h,
        };
        [0.0, baseline]
            .map(|x| Camera::from_camera_to_world(k, glam::Quat::IDENTITY, glam::Vec3::X * x))
            .to_vec()
    }

    #[test]
    fn a_plane_gets_a_range_around_its_depth_inside_the_preset() {
        // fx 100, baseline 0.1 m, disparity 4 px: the plane is at 2.5 m.
        let range = scene_range(&plane_pair(96, 48, 4), &rig(96, 48, 0.1), &Config::tiny())
            .expect("a textured plane is matched");
        assert!(range.near < 2.5 && range.far > 2.5, "{range:?}");
        assert!(range.near >= 1.0 && range.far <= 100.0, "{range:?}");
        assert!(range.far / range.near >= MIN_RATIO - 1e-3, "{range:?}");
        assert!(range.far < 10.0, "{range:?}");
    }

    #[test]
    fn the_rig_range_ignores_float_noise_in_the_camera_positions() {
        let cfg = Config {
            rig_disparity_fraction: Some(0.25),
            ..Config::tiny()
        };
        let at = |origin: glam::Vec3| {
            let mut cameras = rig(96, 48, 0.6);
            for c in &mut cameras {
                *c = Camera::from_camera_to_world(
                    c.intrinsics,
                    glam::Quat::IDENTITY,
                    c.position + origin,
                );
            }
            rig_range(&cameras, &cfg).unwrap()
        };
        let home = at(glam::Vec3::ZERO);
        // fx 100 x 0.6 m / (0.25 x 96 px) = 2.5 m.
        assert!((home.near - 2.5).abs() < 1e-5, "{home:?}");
        // The rig some metres into a bin's frame: its positions' last digits differ.
        for origin in [
            glam::Vec3::new(12.345, -7.1, 3.3),
            glam::Vec3::splat(-123.456),
        ] {
            assert_eq!(at(origin), home, "{origin}");
        }
        assert_eq!(significant_digits(0.59999, 4), 0.6);
        assert_eq!(significant_digits(1234567.0, 4), 1235000.0);
        for x in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert!(significant_digits(x, 4).to_bits() == x.to_bits());
        }
    }

    #[test]
    fn scenes_deeper_than_the_bound_keep_the_preset_range() {
        let (pair, cameras) = (plane_pair(96, 48, 4), rig(96, 48, 0.1));
        let bounded = |max_far| Config {
            auto_depth_range_max_far: Some(max_far),
            ..Config::tiny()
        };
        let unbounded = scene_range(&pair, &cameras, &Config::tiny()).expect("matched");
        assert_eq!(
            scene_range(&pair, &cameras, &bounded(50.0)),
            Some(unbounded)
        );
        // A bound at the plane's own depth is below any range around it.
        assert_eq!(scene_range(&pair, &cameras, &bounded(2.5)), None);
        assert_eq!(scene_range(&pair, &cameras, &bounded(f32::NAN)), None);
    }

    #[test]
    fn flat_images_and_unrectified_pairs_keep_the_preset_range() {
        let flat = Tensor::full(0.5f32, (2, 3, 48, 96), &Device::Cpu).unwrap();
        assert_eq!(scene_range(&flat, &rig(96, 48, 0.1), &Config::tiny()), None);
        let mut cameras = rig(96, 48, 0.1);
        cameras[1] = Camera::from_camera_to_world(
            cameras[1].intrinsics,
            glam::Quat::from_rotation_y(0.2),
            glam::Vec3::X * 0.1,
        );
        let pair = plane_pair(96, 48, 4);
        assert_eq!(scene_range(&pair, &cameras, &Config::tiny()), None);
    }

    #[test]
    fn ranges_at_the_extremes_stay_inside_the_preset_and_finite() {
        let preset = Config::tiny();
        for (near, far) in [
            (1e-6, 1e-5),
            (1e6, 1e7),
            (0.5, 1e9),
            (3.0, 3.0),
            (50.0, 99.0),
        ] {
            let r = range_within(near, far, &preset).expect("finite input");
            assert!(
                r.near >= preset.near && r.far <= preset.far,
                "{near} {far}: {r:?}"
            );
            assert!(
                r.near < r.far && r.far / r.near >= MIN_RATIO - 1e-3,
                "{near} {far}: {r:?}"
            );
        }
        assert_eq!(range_within(f32::NAN, 2.0, &preset), None);
        assert_eq!(range_within(1.0, f32::INFINITY, &preset), None);
    }
}
