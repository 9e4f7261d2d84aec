//! The SGM baseline's disparity range across rigs and image sizes, and its behaviour at the
//! extremes: textured planes rendered by the CPU rasterizer for rigs from 1 mm to 2 m of
//! baseline, with the planes' depth as ground truth.

use glam::{Quat, Vec3};
use model::baseline::{SgmConfig, SgmReconstructor};
use model::frame::RgbImage;
use model::reconstruct::{Reconstructor, StereoView};
use renderer::{Camera, GaussianSet, Intrinsics};

use super::baseline::{all_finite, plane, render};

/// A rectified rig: intrinsics and baseline (metres).
#[derive(Clone, Copy)]
struct Rig {
    k: Intrinsics,
    baseline: f32,
}

impl Rig {
    /// A `width x height` rig with focal `fx` and the principal point at the centre.
    fn new(width: u32, height: u32, fx: f32, baseline: f32) -> Self {
        let k = Intrinsics {
            fx,
            fy: fx,
            cx: (width as f32 - 1.0) / 2.0,
            cy: (height as f32 - 1.0) / 2.0,
            width,
            height,
        };
        Self { k, baseline }
    }

    fn cameras(&self) -> (Camera, Camera) {
        (
            Camera::identity(self.k),
            Camera::from_camera_to_world(self.k, Quat::IDENTITY, Vec3::X * self.baseline),
        )
    }

    /// Disparity of depth `z`, pixels.
    fn disparity(&self, z: f32) -> f32 {
        self.k.fx * self.baseline / z
    }

    /// A textured plane at depth `z` covering both views, or only the middle `share` of the
    /// left view's columns.
    fn plane(&self, set: &mut GaussianSet, z: f32, share: f32, seed: u64) {
        let half_w = (self.k.cx + 4.0) / self.k.fx * z;
        let half_h = (self.k.cy + 4.0) / self.k.fy * z;
        let x = match share < 1.0 {
            true => [-share * half_w, share * half_w],
            false => [-half_w, half_w + self.baseline],
        };
        plane(set, self.k.fx, z, x, [-half_h, half_h], seed);
    }

    /// The rendered left and right images of `set` and the left depth (0 where empty).
    fn pair(&self, set: &GaussianSet) -> (RgbImage, RgbImage, Vec<f32>) {
        let (l, r) = self.cameras();
        let (left, depth) = render(set, &l);
        let (right, _) = render(set, &r);
        (left, right, depth)
    }

    fn view<'a>(&self, left: &'a RgbImage, right: &'a RgbImage) -> StereoView<'a> {
        let (left_camera, right_camera) = self.cameras();
        StereoView {
            left,
            right,
            left_camera,
            right_camera,
        }
    }
}

/// Share of the pixels with truth depth in `columns` whose disparity is off by more than
/// 3 px, an unmatched pixel counting as wrong, and the mean |dz| / z over matched ones.
fn bad3_and_abs_rel(
    rig: &Rig,
    disparity: &[f32],
    depth: &[f32],
    judged: impl Fn(usize, f32) -> bool,
) -> (f32, f32) {
    let w = rig.k.width as usize;
    let (mut n, mut bad, mut rel, mut matched) = (0usize, 0usize, 0.0f32, 0usize);
    for (i, (&d, &z)) in disparity.iter().zip(depth).enumerate() {
        if !(z > 0.0 && judged(i % w, z)) {
            continue;
        }
        n += 1;
        let truth = rig.disparity(z);
        if d.is_nan() || (d - truth).abs() > 3.0 {
            bad += 1;
        }
        if !d.is_nan() {
            matched += 1;
            rel += (rig.disparity(d) - z).abs() / z;
        }
    }
    assert!(n > 0, "no judged pixel");
    (bad as f32 / n as f32, rel / matched.max(1) as f32)
}

#[test]
fn disparities_over_150_px_at_640_px_width_are_found() {
    // A wall at 3.2 m (50 px) and a board at 0.95 m (168 px) over its middle third.
    let rig = Rig::new(640, 96, 320.0, 0.5);
    let (z_wall, z_near) = (3.2, 0.95);
    let mut set = GaussianSet::default();
    rig.plane(&mut set, z_wall, 1.0, 11);
    rig.plane(&mut set, z_near, 0.33, 12);
    let (left, right, depth) = rig.pair(&set);
    let sgm = SgmReconstructor::default();
    let map = sgm.view_disparity(&rig.view(&left, &right)).unwrap();
    // The board's pixels, two columns in from its edges (the edges are depth jumps).
    let near = |z: f32| (z - z_near).abs() < 0.01;
    let board: Vec<usize> = (0..depth.len()).filter(|&i| near(depth[i])).collect();
    let (first, last) = board.iter().fold((usize::MAX, 0), |(a, b), &i| {
        (a.min(i % 640), b.max(i % 640))
    });
    let (bad3, abs_rel) = bad3_and_abs_rel(&rig, &map.disparity, &depth, |x, z| {
        near(z) && x > first + 2 && x + 2 < last
    });
    println!(
        "board at {:.1} px: bad-3 {:.2}% (unmatched counted wrong), AbsRel {abs_rel:.4}",
        rig.disparity(z_near),
        100.0 * bad3
    );
    assert!(bad3 < 0.05, "bad-3 {bad3}");
    assert!(abs_rel < 0.01, "AbsRel {abs_rel}");
}

#[test]
fn the_range_follows_the_rig_and_the_width() {
    let c = SgmConfig::default();
    // 640 px at fx 550: a third is 214 px, a half 320 px; min_depth 0.1 m.
    for (baseline, levels) in [(0.05, 276), (0.5, 321), (0.001, 215), (2.0, 321)] {
        assert_eq!(
            c.levels_for(640, Some((550.0, baseline))),
            levels,
            "{baseline}"
        );
    }
    assert_eq!(c.levels_for(320, None), 108);
    assert_eq!(c.levels_for(1408, Some((552.0, 0.6))), 705);
    assert_eq!(c.levels_for(1, Some((1.0, 1.0))), 1);
    assert_eq!(c.levels_for(640, Some((f32::NAN, 0.1))), 215);
    let fixed = SgmConfig {
        max_disparity: Some(40),
        ..SgmConfig::default()
    };
    assert_eq!(fixed.levels_for(640, Some((550.0, 0.05))), 41);

    // A desk at 0.25 m before a 5 cm rig (64 px) and a room at 1.2 m before a 50 cm rig
    // (133 px), both at 640 px: matched to a fraction of a pixel with the defaults.
    for (baseline, z) in [(0.05, 0.25), (0.5, 1.2)] {
        let rig = Rig::new(640, 64, 320.0, baseline);
        let mut set = GaussianSet::default();
        rig.plane(&mut set, z, 1.0, 21);
        let (left, right, _) = rig.pair(&set);
        let map = SgmReconstructor::default()
            .view_disparity(&rig.view(&left, &right))
            .unwrap();
        let truth = rig.disparity(z);
        let errors: Vec<f32> = (0..map.disparity.len())
            .filter(|i| i % 640 > truth as usize + 8)
            .map(|i| (map.disparity[i] - truth).abs())
            .collect();
        let within = errors.iter().filter(|e| **e < 0.5).count() as f32 / errors.len() as f32;
        println!("baseline {baseline} m, {truth:.1} px: {within:.3} within 0.5 px");
        assert!(within > 0.9, "baseline {baseline}: {within}");
    }
}

#[test]
fn extreme_rigs_and_images_give_finite_output_or_a_typed_error() {
    let rig = |baseline| Rig::new(256, 48, 160.0, baseline);
    let scenes = [
        // A surface at 0.1 m before a 60 cm rig: 960 px, beyond any overlap.
        (rig(0.6), 0.1),
        // A 1 mm rig: 0.08 px at 2 m.
        (rig(0.001), 2.0),
        // A 2 m rig: a wall at 20 m is 16 px.
        (rig(2.0), 20.0),
    ];
    for (rig, z) in scenes {
        let mut set = GaussianSet::default();
        rig.plane(&mut set, z, 1.0, 31);
        let (left, right, _) = rig.pair(&set);
        let view = rig.view(&left, &right);
        let map = SgmReconstructor::default().view_disparity(&view).unwrap();
        assert!(map.disparity.iter().all(|d| d.is_nan() || d.is_finite()));
        assert!(map.confidence.iter().all(|c| c.is_finite()));
        let out = SgmReconstructor::default().reconstruct(&[view]).unwrap();
        println!(
            "baseline {} m, plane at {z} m: {} Gaussians",
            rig.baseline,
            out.len()
        );
        assert!(all_finite(&out));
    }
    // Flat, black and saturated images, and a one-pixel image.
    let flat = rig(0.1);
    for value in [0.0, 0.5, 1.0, 7.0] {
        let mut image = RgbImage::new(256, 48);
        image.data.fill(value);
        let out = SgmReconstructor::default()
            .reconstruct(&[flat.view(&image, &image)])
            .unwrap();
        assert!(out.len() < 50 && all_finite(&out), "{value}: {}", out.len());
    }
    let tiny = Rig::new(1, 1, 1.0, 0.1);
    let pixel = RgbImage::new(1, 1);
    let out = SgmReconstructor::default()
        .reconstruct(&[tiny.view(&pixel, &pixel)])
        .unwrap();
    assert!(all_finite(&out));
}

#[test]
fn sgm_settings_change_the_defaults_and_bad_ones_are_typed_errors() {
    use model::methods::{build, MethodError};
    let set = |s: &[&str]| {
        let settings: Vec<String> = s.iter().map(|v| v.to_string()).collect();
        build("sgm", None, None, &settings)
    };
    assert!(set(&["median=false", "paths=five", "uniqueness_ratio=0.05"]).is_ok());
    for bad in ["paths=six", "median=maybe", "no_such_key=1", "median"] {
        assert!(
            matches!(set(&[bad]), Err(MethodError::Setting(_))),
            "{bad} accepted"
        );
    }
    // A setting the algorithm cannot honour parses but is refused when matching.
    let rig = Rig::new(64, 16, 50.0, 0.1);
    let image = RgbImage::new(64, 16);
    let mut sgm = set(&["p2=9000"]).unwrap();
    assert!(matches!(
        sgm.reconstruct(&[rig.view(&image, &image)]),
        Err(model::reconstruct::ReconstructError::InvalidInput(_))
    ));
}
