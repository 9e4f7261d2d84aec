//! The tf buffer against analytic poses: a robot's five-frame chain with a 10 Hz odometry
//! edge, static mounts, inverses and siblings; every error kind; loops; floods of frame
//! names and samples; malformed transforms; stamps at their extremes; expiry and order.

use glam::{DMat3, DQuat, DVec3};

use super::*;
use crate::msg::geometry_msgs::{Quaternion, Transform, Vector3};
use crate::msg::std_msgs::{Header, Time};
use crate::msg::ConvertError;

/// 100 ms, the odometry period.
const PERIOD: i64 = 100_000_000;
/// The first odometry stamp (2023).
const T0: i64 = 1_700_000_000_000_000_000;

pub(super) fn transform(
    parent: &str,
    child: &str,
    stamp_ns: i64,
    q: DQuat,
    t: DVec3,
) -> TransformStamped {
    TransformStamped {
        header: Header::new(stamp_ns, parent),
        child_frame_id: child.into(),
        transform: Transform {
            translation: Vector3 {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            rotation: Quaternion {
                x: q.x,
                y: q.y,
                z: q.z,
                w: q.w,
            },
        },
    }
}

/// REP 103's optical frame in its camera's body frame: optical x right (body -y), y down
/// (body -z), z forward (body x).
pub(super) fn optical() -> DQuat {
    DQuat::from_mat3(&DMat3::from_cols(
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(0.0, 0.0, -1.0),
        DVec3::new(1.0, 0.0, 0.0),
    ))
}

fn world_odom() -> DAffine3 {
    DAffine3::from_rotation_translation(
        DQuat::from_rotation_z(0.4),
        DVec3::new(100_000.5, -250_000.25, 12.0),
    )
}

fn base_camera() -> DAffine3 {
    DAffine3::from_rotation_translation(DQuat::from_rotation_y(0.1), DVec3::new(0.3, -0.06, 1.2))
}

/// The body's pose in `odom` at sample `k`: 1.5 m/s along x with a sideways sway, yaw 0.05
/// rad per sample.
fn odom_base(k: i64) -> (DQuat, DVec3) {
    let s = k as f64;
    (
        DQuat::from_rotation_z(0.05 * s),
        DVec3::new(0.15 * s, (0.3 * s).sin(), 0.01 * s),
    )
}

/// world -> odom (static), odom -> base_link (10 Hz, samples 0..=n), base_link ->
/// camera_link and camera_link -> camera_optical (static).
fn robot(n: i64) -> TfBuffer {
    let mut tf = TfBuffer::new(TfConfig::default());
    let w = world_odom();
    let b = base_camera();
    let statics = [
        ("world", "odom", DQuat::from_mat3(&w.matrix3), w.translation),
        (
            "base_link",
            "camera_link",
            DQuat::from_mat3(&b.matrix3),
            b.translation,
        ),
        ("camera_link", "camera_optical", optical(), DVec3::ZERO),
    ];
    for (parent, child, q, t) in statics {
        tf.insert(&transform(parent, child, T0, q, t), true)
            .unwrap();
    }
    for k in 0..=n {
        let (q, t) = odom_base(k);
        tf.insert(
            &transform("odom", "base_link", T0 + k * PERIOD, q, t),
            false,
        )
        .unwrap();
    }
    tf
}

/// The largest difference between the images of a few points under `a` and `b`.
pub(super) fn distance(a: &DAffine3, b: &DAffine3) -> f64 {
    [DVec3::ZERO, DVec3::X, DVec3::new(-2.0, 3.0, 10.0)]
        .into_iter()
        .map(|p| (a.transform_point3(p) - b.transform_point3(p)).length())
        .fold(0.0, f64::max)
}

#[test]
fn the_optical_rotation_is_rep_103s() {
    let q = optical();
    let want = DQuat::from_xyzw(-0.5, 0.5, -0.5, 0.5);
    assert!(q.dot(want).abs() > 1.0 - 1e-15, "{q}");
    assert!((q * DVec3::Z - DVec3::X).length() < 1e-15);
}

#[test]
fn a_stamp_between_samples_is_the_analytic_interpolation() {
    let tf = robot(20);
    let mount = base_camera() * DAffine3::from_quat(optical());
    for (k, fraction) in [(3, 0.37), (0, 0.0), (7, 0.5), (19, 0.999)] {
        let stamp = T0 + k * PERIOD + (fraction * PERIOD as f64) as i64;
        let exact = (stamp - T0 - k * PERIOD) as f64 / PERIOD as f64;
        // Both samples rotate about z: the slerp is the yaw interpolated.
        let s = k as f64 + exact;
        let (_, t0) = odom_base(k);
        let (_, t1) = odom_base(k + 1);
        let body = DAffine3::from_rotation_translation(
            DQuat::from_rotation_z(0.05 * s),
            t0.lerp(t1, exact),
        );
        let want = world_odom() * body * mount;
        let got = tf.lookup("world", "camera_optical", stamp).unwrap();
        assert!(
            distance(&got, &want) < 1e-9,
            "k {k}: {}",
            distance(&got, &want)
        );
        assert!(
            (got.matrix3 - want.matrix3)
                .abs()
                .to_cols_array()
                .iter()
                .all(|d| *d < 1e-12),
            "k {k}"
        );
    }
    // At a sample's own stamp, the sample.
    let (q, t) = odom_base(4);
    let want = DAffine3::from_rotation_translation(q, t);
    let got = tf.lookup("odom", "base_link", T0 + 4 * PERIOD).unwrap();
    assert!(distance(&got, &want) < 1e-12);
}

#[test]
fn static_paths_hold_at_any_stamp_and_mounts_come_from_them() {
    let tf = robot(3);
    let mount = base_camera() * DAffine3::from_quat(optical());
    for stamp in [i64::MIN, -1, 1, T0, i64::MAX] {
        let got = tf.lookup("base_link", "camera_optical", stamp).unwrap();
        assert!(distance(&got, &mount) < 1e-12, "{stamp}");
    }
    let got = tf.lookup_static("base_link", "camera_optical").unwrap();
    assert!(distance(&got, &mount) < 1e-12);
    assert_eq!(
        tf.lookup_static("world", "camera_optical"),
        Err(TfError::NotStatic {
            parent: "odom".into(),
            child: "base_link".into()
        })
    );
    // A point 10 m ahead of the optical frame is 10 m along camera_link's x.
    let ahead = tf
        .lookup("camera_link", "camera_optical", T0)
        .unwrap()
        .transform_point3(DVec3::new(0.0, 0.0, 10.0));
    assert!((ahead - DVec3::new(10.0, 0.0, 0.0)).length() < 1e-12);
}

#[test]
fn the_inverse_direction_is_the_inverse() {
    let tf = robot(10);
    let stamp = T0 + 5 * PERIOD + 12_345_678;
    let forward = tf.lookup("world", "camera_optical", stamp).unwrap();
    let back = tf.lookup("camera_optical", "world", stamp).unwrap();
    assert!(distance(&(back * forward), &DAffine3::IDENTITY) < 1e-9);
    assert!(distance(&back, &forward.inverse()) < 1e-9);
    // Itself: the identity, known or not (as tf2).
    assert_eq!(tf.lookup("nowhere", "nowhere", T0), Ok(DAffine3::IDENTITY));
}

#[test]
fn siblings_meet_at_their_common_ancestor() {
    let mut tf = robot(10);
    let lidar = DAffine3::from_rotation_translation(
        DQuat::from_rotation_x(0.2),
        DVec3::new(-0.2, 0.0, 1.8),
    );
    let q = DQuat::from_mat3(&lidar.matrix3);
    tf.insert(
        &transform("base_link", "lidar", T0, q, lidar.translation),
        true,
    )
    .unwrap();
    let want = lidar.inverse() * base_camera() * DAffine3::from_quat(optical());
    let got = tf.lookup("lidar", "camera_optical", T0 + 333).unwrap();
    assert!(distance(&got, &want) < 1e-12);
    // Across the dynamic edge: lidar in odom equals odom <- base_link <- lidar.
    let stamp = T0 + 2 * PERIOD;
    let (q, t) = odom_base(2);
    let want = DAffine3::from_rotation_translation(q, t) * lidar;
    let got = tf.lookup("odom", "lidar", stamp).unwrap();
    assert!(distance(&got, &want) < 1e-12);
}

#[test]
fn each_lookup_error_is_the_one_tf2_gives() {
    let mut tf = robot(10);
    tf.insert(
        &transform("map2", "x", T0, DQuat::IDENTITY, DVec3::ZERO),
        true,
    )
    .unwrap();
    assert_eq!(
        tf.lookup("world", "ghost", T0),
        Err(TfError::UnknownFrame("ghost".into()))
    );
    assert_eq!(
        tf.lookup("x", "camera_optical", T0),
        Err(TfError::NotConnected {
            target_frame: "x".into(),
            source_frame: "camera_optical".into()
        })
    );
    assert_eq!(
        tf.lookup("world", "camera_optical", T0 - 1),
        Err(TfError::ExtrapolationPast {
            parent: "odom".into(),
            child: "base_link".into(),
            stamp_ns: T0 - 1,
            oldest_ns: T0,
        })
    );
    assert_eq!(
        tf.lookup("world", "camera_optical", T0 + 10 * PERIOD + 1),
        Err(TfError::ExtrapolationFuture {
            parent: "odom".into(),
            child: "base_link".into(),
            stamp_ns: T0 + 10 * PERIOD + 1,
            newest_ns: T0 + 10 * PERIOD,
        })
    );
    for stamp in [i64::MIN, i64::MAX] {
        assert!(tf.lookup("world", "camera_optical", stamp).is_err());
    }
    // An edge with one sample is read at that stamp only (tf2 allows no extrapolation).
    let mut one = TfBuffer::new(TfConfig::default());
    one.insert(&transform("a", "b", T0, DQuat::IDENTITY, DVec3::X), false)
        .unwrap();
    assert!(one.lookup("a", "b", T0).is_ok());
    assert!(matches!(
        one.lookup("a", "b", T0 + 1),
        Err(TfError::ExtrapolationFuture { .. })
    ));
}

#[test]
fn a_transform_that_would_close_a_loop_is_refused() {
    let mut tf = TfBuffer::new(TfConfig::default());
    let t = |p: &str, c: &str| transform(p, c, T0, DQuat::IDENTITY, DVec3::X);
    tf.insert(&t("a", "b"), true).unwrap();
    tf.insert(&t("b", "c"), true).unwrap();
    assert_eq!(
        tf.insert(&t("c", "a"), true),
        Err(TfError::Loop {
            parent: "c".into(),
            child: "a".into()
        })
    );
    assert_eq!(tf.counts().loops, 1);
    // The tree is as it was: a is a root, c two steps below it.
    assert_eq!(tf.parent("a"), None);
    let got = tf.lookup("a", "c", T0).unwrap();
    assert!((got.translation - DVec3::new(2.0, 0.0, 0.0)).length() < 1e-15);
    // Re-parenting c to a is no loop: the latest wins.
    tf.insert(&t("a", "c"), true).unwrap();
    assert_eq!(tf.parent("c"), Some("a"));
    assert_eq!(tf.counts().replaced_edges, 1);
}

#[test]
fn a_second_parent_wins_when_newer_and_is_refused_when_older() {
    let mut tf = robot(10);
    let newest = T0 + 10 * PERIOD;
    let from_map = |stamp| transform("map", "base_link", stamp, DQuat::IDENTITY, DVec3::Y);
    assert_eq!(
        tf.insert(&from_map(newest - 1), false),
        Err(TfError::StaleParent {
            parent: "map".into(),
            child: "base_link".into(),
            current_parent: "odom".into(),
            stamp_ns: newest - 1,
            newest_ns: newest,
        })
    );
    assert_eq!(tf.parent("base_link"), Some("odom"));
    tf.insert(&from_map(newest + 1), false).unwrap();
    assert_eq!(tf.parent("base_link"), Some("map"));
    // The old parent's samples are gone with its edge.
    assert_eq!(
        tf.lookup("world", "camera_optical", newest),
        Err(TfError::NotConnected {
            target_frame: "world".into(),
            source_frame: "camera_optical".into()
        })
    );
    let got = tf.lookup("map", "camera_link", newest + 1).unwrap();
    assert!((got.translation - (DVec3::Y + base_camera().translation)).length() < 1e-12);
}

#[test]
fn a_flood_of_frame_names_stays_bounded() {
    let mut tf = TfBuffer::new(TfConfig::default());
    let max = tf.config().max_frames;
    for i in 0..100_000 {
        let t = transform("world", &format!("f{i}"), T0 + i, DQuat::IDENTITY, DVec3::X);
        let _ = tf.insert(&t, i % 2 == 0);
    }
    assert_eq!(tf.frames().count(), max);
    let counts = tf.counts();
    assert_eq!(counts.inserted, max as u64 - 1);
    assert_eq!(counts.frames_full, 100_000 - (max as u64 - 1));
    assert!(matches!(
        tf.insert(&transform("world", "new", T0, DQuat::IDENTITY, DVec3::X), true),
        Err(TfError::TooManyFrames { max: m, .. }) if m == max
    ));
    // Known frames still take transforms.
    tf.insert(
        &transform("world", "f1", T0 + 7, DQuat::IDENTITY, DVec3::Y),
        false,
    )
    .unwrap();
    // And samples on one edge stop at the per-edge cap: 1 kHz for 5 s, 10 s of cache.
    let mut fast = TfBuffer::new(TfConfig::default());
    for i in 0..5_000 {
        let t = transform(
            "odom",
            "base_link",
            T0 + i * 1_000_000,
            DQuat::IDENTITY,
            DVec3::X,
        );
        fast.insert(&t, false).unwrap();
    }
    assert_eq!(fast.dynamic_samples(), 1000);
    assert_eq!(fast.counts().capped, 4000);
    assert!(fast.lookup("odom", "base_link", T0 + 4_000_000_000).is_ok());
    assert!(matches!(
        fast.lookup("odom", "base_link", T0 + 3_998_000_000),
        Err(TfError::ExtrapolationPast { .. })
    ));
}

#[test]
fn malformed_transforms_are_refused_with_their_reason() {
    let mut tf = TfBuffer::new(TfConfig::default());
    let good = transform("a", "b", T0, DQuat::IDENTITY, DVec3::X);
    let quat = |x, y, z, w| Quaternion { x, y, z, w };
    type Spoil = fn(&mut TransformStamped);
    let cases: [(Spoil, ConvertError); 5] = [
        (
            |t| t.transform.translation.y = f64::NAN,
            ConvertError::NonFinite("translation.y"),
        ),
        (
            |t| t.transform.rotation.z = f64::INFINITY,
            ConvertError::NonFinite("rotation.z"),
        ),
        (
            |t| {
                t.transform.rotation = Quaternion {
                    w: 0.0,
                    ..t.transform.rotation
                }
            },
            ConvertError::NonUnitQuaternion {
                norm: 0.0,
                tolerance: crate::msg::pose::UNIT_TOLERANCE,
            },
        ),
        (
            |t| t.transform.rotation.w = 2.0,
            ConvertError::NonUnitQuaternion {
                norm: 2.0,
                tolerance: crate::msg::pose::UNIT_TOLERANCE,
            },
        ),
        (
            |t| t.transform.rotation.x = f64::NEG_INFINITY,
            ConvertError::NonFinite("rotation.x"),
        ),
    ];
    for (spoil, reason) in cases {
        let mut t = good.clone();
        spoil(&mut t);
        assert_eq!(
            tf.insert(&t, false),
            Err(TfError::Invalid {
                parent: "a".into(),
                child: "b".into(),
                source: reason
            })
        );
    }
    let mut empty = good.clone();
    empty.child_frame_id.clear();
    assert_eq!(
        tf.insert(&empty, true),
        Err(TfError::EmptyFrameName("child_frame_id"))
    );
    let mut same = good.clone();
    same.child_frame_id = "a".into();
    assert_eq!(tf.insert(&same, true), Err(TfError::SameFrame("a".into())));
    let mut long = good.clone();
    long.header.frame_id = "x".repeat(257);
    assert_eq!(
        tf.insert(&long, true),
        Err(TfError::NameTooLong { len: 257, max: 256 })
    );
    assert_eq!(tf.counts().invalid, 8);
    assert_eq!(
        tf.frames().count(),
        0,
        "no frame is made by a refused transform"
    );
    // Within the tolerance a quaternion is normalised.
    let mut near = good.clone();
    near.transform.rotation = quat(0.0, 0.0, 0.0, 1.0 + 5e-6);
    tf.insert(&near, true).unwrap();
    let got = tf.lookup("a", "b", 0).unwrap();
    assert!((got.matrix3.determinant() - 1.0).abs() < 1e-12);
}

#[test]
fn stamps_at_their_extremes_neither_overflow_nor_panic() {
    let mut tf = TfBuffer::new(TfConfig {
        cache_ns: i64::MAX,
        ..TfConfig::default()
    });
    let first = Time {
        sec: i32::MIN,
        nanosec: 0,
    }
    .to_nanos();
    let last = Time {
        sec: i32::MAX,
        nanosec: 999_999_999,
    }
    .to_nanos();
    for (stamp, x) in [(last, 1.0), (first, -1.0)] {
        tf.insert(
            &transform("a", "b", stamp, DQuat::IDENTITY, DVec3::new(x, 0.0, 0.0)),
            false,
        )
        .unwrap();
    }
    let mid = first + (last - first) / 2;
    let got = tf.lookup("a", "b", mid).unwrap();
    assert!(got.translation.x.abs() < 1e-9, "{}", got.translation.x);
    assert_eq!(tf.lookup("a", "b", first).unwrap().translation.x, -1.0);
    assert_eq!(tf.lookup("a", "b", LATEST).unwrap().translation.x, 1.0);
    assert!(matches!(
        tf.lookup("a", "b", i64::MIN),
        Err(TfError::ExtrapolationPast { .. })
    ));
    assert!(matches!(
        tf.lookup("a", "b", i64::MAX),
        Err(TfError::ExtrapolationFuture { .. })
    ));
    // A cache of no length (or a negative one) keeps the newest sample alone.
    for cache_ns in [0, -5, i64::MIN] {
        let mut none = TfBuffer::new(TfConfig {
            cache_ns,
            ..TfConfig::default()
        });
        let t = |stamp| transform("a", "b", stamp, DQuat::IDENTITY, DVec3::X);
        none.insert(&t(T0), false).unwrap();
        none.insert(&t(T0 + 1), false).unwrap();
        assert!(matches!(
            none.insert(&t(T0), false),
            Err(TfError::TooOld { .. })
        ));
        assert_eq!(none.dynamic_samples(), 1, "cache {cache_ns}");
        assert!(none.lookup("a", "b", T0 + 1).is_ok());
        assert!(none.lookup("a", "b", i64::MIN).is_err());
    }
    // With the default cache the far past is too old.
    let mut short = TfBuffer::new(TfConfig::default());
    let t = |stamp| transform("a", "b", stamp, DQuat::IDENTITY, DVec3::X);
    short.insert(&t(last), false).unwrap();
    assert!(matches!(
        short.insert(&t(first), false),
        Err(TfError::TooOld { .. })
    ));
}

#[test]
fn samples_expire_behind_the_newest_and_may_come_out_of_order() {
    let mut tf = TfBuffer::new(TfConfig::default());
    let t = |k: i64| {
        let (q, t) = odom_base(k);
        transform("odom", "base_link", T0 + k * PERIOD, q, t)
    };
    // 30 s at 10 Hz, odd samples first, even ones after (the cache holds 10 s).
    for k in (1..=300).step_by(2) {
        tf.insert(&t(k), false).unwrap();
    }
    for k in (200..=300).step_by(2) {
        tf.insert(&t(k), false).unwrap();
    }
    assert_eq!(tf.dynamic_samples(), 101);
    assert_eq!(
        tf.lookup("odom", "base_link", T0 + 150 * PERIOD),
        Err(TfError::ExtrapolationPast {
            parent: "odom".into(),
            child: "base_link".into(),
            stamp_ns: T0 + 150 * PERIOD,
            oldest_ns: T0 + 200 * PERIOD,
        })
    );
    assert!(matches!(
        tf.insert(&t(100), false),
        Err(TfError::TooOld { .. })
    ));
    assert!(matches!(
        tf.insert(&t(250), false),
        Err(TfError::Repeated { .. })
    ));
    assert_eq!((tf.counts().too_old, tf.counts().repeated), (1, 1));
    // The even samples filled in between: the lookup at one is exact, not interpolated.
    let (q, p) = odom_base(250);
    let got = tf.lookup("odom", "base_link", T0 + 250 * PERIOD).unwrap();
    assert!(distance(&got, &DAffine3::from_rotation_translation(q, p)) < 1e-12);
}

#[test]
fn latest_is_the_newest_time_every_dynamic_edge_has() {
    let mut tf = robot(10);
    // A second dynamic edge, world <- drone, newest at sample 6.
    for k in 0..=6 {
        let t = transform(
            "world",
            "drone",
            T0 + k * PERIOD,
            DQuat::IDENTITY,
            DVec3::Z * k as f64,
        );
        tf.insert(&t, false).unwrap();
    }
    let common = T0 + 6 * PERIOD;
    assert_eq!(
        tf.latest_common("drone", "camera_optical"),
        Ok(Some(common))
    );
    assert_eq!(
        tf.lookup("drone", "camera_optical", LATEST),
        tf.lookup("drone", "camera_optical", common)
    );
    assert_eq!(
        tf.latest_common("world", "base_link"),
        Ok(Some(T0 + 10 * PERIOD))
    );
    // A static path has no latest time; a lookup there holds at any stamp.
    assert_eq!(tf.latest_common("base_link", "camera_optical"), Ok(None));
    assert!(tf.lookup("base_link", "camera_optical", LATEST).is_ok());
}

#[test]
fn a_leading_slash_names_the_same_frame_as_tf2_strips_it() {
    let mut tf = robot(2);
    let t = transform("/base_link", "/lidar", T0, DQuat::IDENTITY, DVec3::Z);
    tf.insert(&t, true).unwrap();
    assert_eq!(tf.parent("lidar"), Some("base_link"));
    assert_eq!(tf.parent("/lidar"), Some("base_link"));
    assert_eq!(tf.frames().filter(|f| f.starts_with('/')).count(), 0);
    let plain = tf.lookup("world", "lidar", T0 + PERIOD).unwrap();
    let slashed = tf.lookup("/world", "/lidar", T0 + PERIOD).unwrap();
    assert_eq!(plain, slashed);
    assert_eq!(tf.lookup("/lidar", "lidar", T0), Ok(DAffine3::IDENTITY));
    assert_eq!(
        tf.latest_common("/world", "lidar"),
        Ok(Some(T0 + 2 * PERIOD))
    );
    // One slash only, as tf2: `/` alone is empty, `//a` is the frame `/a`.
    let bare = transform("/", "a", T0, DQuat::IDENTITY, DVec3::Z);
    assert_eq!(
        tf.insert(&bare, true),
        Err(TfError::EmptyFrameName("header.frame_id"))
    );
    tf.insert(
        &transform("world", "//a", T0, DQuat::IDENTITY, DVec3::Z),
        true,
    )
    .unwrap();
    assert_eq!(tf.parent("//a"), Some("world"));
    assert!(tf.frames().any(|f| f == "/a"));
    assert_eq!(tf.parent("a"), None);
}
