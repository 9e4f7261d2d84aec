//! The network's candidates from the rig (`rig_disparity_fraction`): the nearest candidate
//! sits at a fixed share of the image width in disparity for any baseline and any image size,
//! the span of the preset is kept, and absurd rigs stay finite inside the safety limits.

use glam::{Quat, Vec3};
use model::net::depth_range::rig_range;
use model::net::{Config, RIG_DEPTH_LIMITS};
use renderer::{Camera, Intrinsics};

/// A rectified pair: `width` px wide with a 90-degree lens, the right camera `baseline`
/// metres along +x.
fn pair(width: u32, baseline: f32) -> [Camera; 2] {
    let k = Intrinsics::from_hfov(width, width / 4, 90.0);
    let at = |x: f32| Camera::from_camera_to_world(k, Quat::IDENTITY, Vec3::new(x, 0.0, 0.0));
    [at(0.0), at(baseline)]
}

fn rigged(fraction: f32) -> Config {
    Config {
        rig_disparity_fraction: Some(fraction),
        ..Config::tiny()
    }
}

#[test]
fn kitti360s_share_gives_the_trained_metres_on_its_rig_and_presets_keep_metres() {
    // KITTI-360's rig at 1408 px (fx 552.554 px, baseline 0.5942 m): 1-100 m as trained.
    let k = Intrinsics {
        fx: 552.554,
        fy: 552.554,
        cx: 682.0,
        cy: 238.0,
        width: 1408,
        height: 376,
    };
    let at = |x: f32| Camera::from_camera_to_world(k, Quat::IDENTITY, Vec3::new(x, 0.0, 0.0));
    let cfg = rigged(0.233_181);
    let r = rig_range(&[at(0.0), at(0.5942)], &cfg).expect("a usable rig");
    assert!(
        (r.near - 1.0).abs() < 2e-3 && (r.far - 100.0).abs() < 0.2,
        "{r:?}"
    );
    // A 10 cm desk rig with the same lens reaches 17 cm.
    let desk = rig_range(&[at(0.0), at(0.1)], &cfg).unwrap();
    assert!((desk.near - 0.168).abs() < 2e-3, "{desk:?}");
    // `tiny`'s and `tiny-3d`'s candidates follow the rig; `small` has no weights trained
    // for it.
    assert_eq!(Config::tiny().rig_disparity_fraction, Some(0.233_181));
    assert_eq!(Config::tiny_3d().rig_disparity_fraction, Some(0.233_181));
    assert_eq!(rig_range(&pair(640, 0.1), &Config::small()), None);
}

#[test]
fn the_nearest_candidate_has_a_third_of_the_width_in_disparity_at_5_cm_and_50_cm() {
    let cfg = rigged(1.0 / 3.0);
    for baseline in [0.05f32, 0.5] {
        for width in [320u32, 640, 1408] {
            let cams = pair(width, baseline);
            let r = rig_range(&cams, &cfg).expect("a usable rig");
            let fx = cams[0].intrinsics.fx;
            let d_near = fx * baseline / r.near;
            let d_far = fx * baseline / r.far;
            assert!(
                (d_near - width as f32 / 3.0).abs() < 1e-3 * width as f32,
                "{d_near}"
            );
            // The preset's span (1..100 m) is kept: far is 100 times near.
            assert!((r.far / r.near - 100.0).abs() < 1e-3, "{r:?}");
            assert!(d_far > 0.0 && d_far < d_near);
        }
        // The same lens at any image size gives the same metres.
        let (a, b) = (
            rig_range(&pair(320, baseline), &cfg).unwrap(),
            rig_range(&pair(1408, baseline), &cfg).unwrap(),
        );
        assert!((a.near - b.near).abs() < 1e-4 * a.near, "{a:?} {b:?}");
    }
    // A 5 cm rig with a 90-degree lens reaches 7.5 cm; a 50 cm one 75 cm.
    let near = |b| rig_range(&pair(640, b), &cfg).unwrap().near;
    assert!((near(0.05) - 0.075).abs() < 1e-4, "{}", near(0.05));
    assert!((near(0.5) - 0.75).abs() < 1e-3, "{}", near(0.5));
}

#[test]
fn absurd_rigs_stay_finite_within_the_limits_or_keep_the_preset() {
    let cfg = rigged(1.0 / 3.0);
    let (lo, hi) = RIG_DEPTH_LIMITS;
    for baseline in [0.001f32, 2.0, 1e6] {
        let r = rig_range(&pair(640, baseline), &cfg).expect("finite rig");
        assert!(r.near.is_finite() && r.far.is_finite(), "{r:?}");
        assert!(
            r.near >= lo && r.far <= hi * 1.0001 && r.near < r.far,
            "{r:?}"
        );
    }
    // No baseline, a NaN camera, a single camera, a zero fraction: the preset's metres.
    assert_eq!(rig_range(&pair(640, 0.0), &cfg), None);
    let mut nan = pair(640, 0.1);
    nan[1].position.x = f32::NAN;
    assert_eq!(rig_range(&nan, &cfg), None);
    assert_eq!(rig_range(&pair(640, 0.1)[..1], &cfg), None);
    assert_eq!(rig_range(&pair(640, 0.1), &rigged(0.0)), None);
}
