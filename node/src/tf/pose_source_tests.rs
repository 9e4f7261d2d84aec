//! The pose source against analytic poses: a robot's tree (map -> odom moving slowly at
//! 5 Hz, odom -> base_link at 50 Hz, static camera mounts) with 10 Hz images between tf
//! samples, played in arrival order; images waiting for their tf; missing links, loops,
//! NaN transforms; Odometry with a static or fixed mount; floods and stamps at extremes.

use glam::{DAffine3, DQuat, DVec3};

use super::*;
use crate::msg::geometry_msgs::{Point, Pose, Quaternion, TransformStamped};
use crate::msg::pose::{affine_from_pose, pose_from_affine};
use crate::msg::std_msgs::{Header, Time};
use crate::tf::tests::{distance, optical, transform};

/// The first stamp (2023).
const T0: i64 = 1_700_000_000_000_000_000;
const MS: i64 = 1_000_000;
/// The tf samples' and images' transport delays.
const TF_DELAY: i64 = 5 * MS;
const IMAGE_DELAY: i64 = 30 * MS;

fn secs(stamp: i64) -> f64 {
    (stamp - T0) as f64 * 1e-9
}

/// odom in map: drifting 2 cm/s and 2 mrad/s, 100 km out. Linear translation and a constant
/// rate about one axis, so the buffer's lerp and slerp are exact between samples.
fn map_odom(stamp: i64) -> DAffine3 {
    let s = secs(stamp);
    DAffine3::from_rotation_translation(
        DQuat::from_rotation_z(0.4 + 0.002 * s),
        DVec3::new(100_000.5 + 0.02 * s, -250_000.25 - 0.01 * s, 12.0),
    )
}

/// base_link in odom: 1.5 m/s ahead, drifting sideways and up, yawing 0.5 rad/s.
fn odom_base(stamp: i64) -> DAffine3 {
    let s = secs(stamp);
    DAffine3::from_rotation_translation(
        DQuat::from_rotation_z(0.5 * s),
        DVec3::new(1.5 * s, 0.3 * s, 0.01 * s),
    )
}

/// camera_optical in base_link: camera_link 0.3 m ahead, 1.2 m up, pitched, then REP 103.
fn mount() -> DAffine3 {
    let link = DAffine3::from_rotation_translation(
        DQuat::from_rotation_y(0.1),
        DVec3::new(0.3, -0.06, 1.2),
    );
    link * DAffine3::from_quat(optical())
}

fn edge(parent: &str, child: &str, stamp: i64, a: &DAffine3) -> TransformStamped {
    let q = DQuat::from_mat3(&a.matrix3);
    transform(parent, child, stamp, q, a.translation)
}

fn tf(transforms: Vec<TransformStamped>) -> TfMessage {
    TfMessage { transforms }
}

fn statics() -> TfMessage {
    let link = mount() * DAffine3::from_quat(optical()).inverse();
    tf(vec![
        edge("base_link", "camera_link", T0, &link),
        edge(
            "camera_link",
            "camera_optical",
            T0,
            &DAffine3::from_quat(optical()),
        ),
    ])
}

fn odometry(stamp: i64) -> Odometry {
    let a = odom_base(stamp);
    let q = DQuat::from_mat3(&a.matrix3);
    let mut msg = Odometry {
        header: Header::new(stamp, "odom"),
        child_frame_id: "base_link".into(),
        ..Odometry::default()
    };
    let (x, y, z) = a.translation.into();
    msg.pose.pose = Pose {
        position: Point { x, y, z },
        orientation: Quaternion {
            x: q.x,
            y: q.y,
            z: q.z,
            w: q.w,
        },
    };
    msg
}

/// Something that reaches the pose source.
enum Input {
    Tf(TfMessage, bool),
    Odometry(Box<Odometry>),
    Image(i64),
}

/// `seconds` of a robot as it arrives: tf_static first, map -> odom every 200 ms and
/// odom -> base_link (on /tf, or as Odometry) every 20 ms, 5 ms after their stamps; images
/// 7 ms after each 100 ms, 30 ms after their stamps. Sorted by arrival.
fn robot(seconds: i64, as_odometry: bool) -> Vec<(i64, Input)> {
    let mut inputs = vec![(T0, Input::Tf(statics(), true))];
    for k in 0..=seconds * 50 {
        let stamp = T0 + k * 20 * MS;
        let at = stamp + TF_DELAY;
        if k % 10 == 0 {
            let t = edge("map", "odom", stamp, &map_odom(stamp));
            inputs.push((at, Input::Tf(tf(vec![t]), false)));
        }
        inputs.push(match as_odometry {
            true => (at, Input::Odometry(Box::new(odometry(stamp)))),
            false => {
                let t = edge("odom", "base_link", stamp, &odom_base(stamp));
                (at, Input::Tf(tf(vec![t]), false))
            }
        });
    }
    for k in 0..seconds * 10 {
        let stamp = T0 + 7 * MS + k * 100 * MS;
        inputs.push((stamp + IMAGE_DELAY, Input::Image(stamp)));
    }
    inputs.sort_by_key(|(at, _)| *at);
    inputs
}

/// Feeds `inputs` (each at its arrival, the node's clock), taking the ready poses after
/// each: (when it came out, stamp, pose).
fn play(source: &mut PoseSource, inputs: &[(i64, Input)]) -> Vec<(i64, i64, DAffine3)> {
    let mut out = Vec::new();
    for (now, input) in inputs {
        match input {
            Input::Tf(msg, is_static) => source.on_tf(msg, *is_static),
            Input::Odometry(msg) => source.on_odometry(msg),
            Input::Image(stamp) => source.on_image(*stamp, "camera_optical", *now),
        }
        let ready = source.take_ready(*now);
        out.extend(ready.into_iter().map(|(stamp, pose)| (*now, stamp, pose)));
    }
    out
}

fn tf_source(world: &str) -> PoseSource {
    let config = PoseSourceConfig::new(PoseSourceKind::Tf, Some(world.into()));
    PoseSource::new(config).unwrap()
}

/// Within 1e-9 m (at points up to 10 m from the camera) and 1e-9 rad of `want`, and a pose
/// the node's PoseStamped check reads back.
fn assert_pose(got: &DAffine3, want: &DAffine3, what: &str) {
    assert!(
        distance(got, want) < 1e-9,
        "{what}: {}",
        distance(got, want)
    );
    let rotation = (got.matrix3 - want.matrix3).abs().to_cols_array();
    assert!(rotation.iter().all(|d| *d < 1e-9), "{what}: {rotation:?}");
    let back = affine_from_pose(&pose_from_affine(got, Header::default())).unwrap();
    assert!(distance(&back, got) < 1e-9, "{what}");
}

fn count(source: &PoseSource, name: &str) -> u64 {
    let counts = source.counts();
    counts.iter().find(|(n, _)| *n == name).unwrap().1
}

#[test]
fn every_image_gets_the_analytic_pose_when_its_tf_arrives() {
    let mut source = tf_source("map");
    let out = play(&mut source, &robot(3, false));
    assert_eq!(out.len(), 30);
    for (i, (at, stamp, pose)) in out.iter().enumerate() {
        assert_eq!(*stamp, T0 + 7 * MS + i as i64 * 100 * MS, "in stamp order");
        assert_pose(
            pose,
            &(map_odom(*stamp) * odom_base(*stamp) * mount()),
            "tf",
        );
        // Out when map -> odom's next 5 Hz sample arrived (odom -> base_link's 50 Hz one came
        // before the image): the images waited for it.
        let next_map = T0 + (stamp - T0).div_euclid(200 * MS) * 200 * MS + 200 * MS;
        assert_eq!(*at, (next_map + TF_DELAY).max(stamp + IMAGE_DELAY), "{i}");
    }
    assert_eq!(source.pending(), 0);
    let c = source.counts();
    assert_eq!(
        &c[..4],
        &[
            ("pose_source/ready", 30),
            ("pose_source/timed_out", 0),
            ("pose_source/failed", 0),
            ("pose_source/overflow", 0)
        ]
    );
    assert_eq!(c[5], ("tf/inserted", 2 + 151 + 16));
    assert!(c[6..].iter().all(|(_, n)| *n == 0), "{c:?}");
}

#[test]
fn an_image_older_than_its_tf_is_ready_at_once_and_one_in_the_cache_past_fails_at_once() {
    let mut source = tf_source("/map");
    let inputs: Vec<_> = robot(12, false)
        .into_iter()
        .filter(|(_, i)| !matches!(i, Input::Image(_)))
        .collect();
    assert!(play(&mut source, &inputs).is_empty());
    let now = T0 + 12 * 1000 * MS;
    let stamp = T0 + 11_503 * MS;
    source.on_image(stamp, "/camera_optical", now);
    let ready = source.take_ready(now);
    assert_eq!(ready.len(), 1);
    assert_eq!(ready[0].0, stamp);
    let want = map_odom(stamp) * odom_base(stamp) * mount();
    assert_pose(&ready[0].1, &want, "immediate");
    // 10 s behind the newest sample: no longer held, given up without waiting.
    source.on_image(T0 + 1003 * MS, "camera_optical", now);
    assert!(source.take_ready(now).is_empty());
    assert_eq!(count(&source, "pose_source/failed"), 1);
    assert!(matches!(
        source.last_given_up(),
        Some(GiveUp::Failed {
            source: TfError::ExtrapolationPast { .. },
            ..
        })
    ));
}

#[test]
fn a_link_that_stops_times_out_and_one_never_sent_fails_after_the_wait() {
    let mut source = tf_source("map");
    // odom -> base_link stops after 1 s.
    let inputs: Vec<_> = robot(2, false)
        .into_iter()
        .filter(|(at, i)| !matches!(i, Input::Image(_)) && *at < T0 + 1000 * MS)
        .collect();
    play(&mut source, &inputs);
    let now = T0 + 1300 * MS;
    source.on_image(T0 + 1207 * MS, "camera_optical", now);
    source.on_image(T0 + 1207 * MS, "lidar", now);
    assert!(source.take_ready(now + DEFAULT_WAIT_NS - 1).is_empty());
    assert_eq!(source.pending(), 2, "both wait");
    assert!(source.take_ready(now + DEFAULT_WAIT_NS).is_empty());
    assert_eq!(source.pending(), 0);
    assert_eq!(count(&source, "pose_source/timed_out"), 1);
    assert_eq!(count(&source, "pose_source/failed"), 1);
    assert_eq!(
        source.last_given_up(),
        Some(&GiveUp::Failed {
            stamp_ns: T0 + 1207 * MS,
            frame: "lidar".into(),
            source: TfError::UnknownFrame("lidar".into()),
        })
    );
    // The timed-out one named the edge that stopped.
    source.on_image(T0 + 1207 * MS, "camera_optical", now);
    source.take_ready(i64::MAX);
    let Some(GiveUp::TimedOut { source: e, .. }) = source.last_given_up() else {
        panic!("{:?}", source.last_given_up());
    };
    assert_eq!(
        e,
        &TfError::ExtrapolationFuture {
            parent: "odom".into(),
            child: "base_link".into(),
            stamp_ns: T0 + 1207 * MS,
            newest_ns: T0 + 980 * MS,
        }
    );
}

#[test]
fn a_loop_in_the_tree_is_refused_and_its_frames_fail() {
    let mut source = tf_source("map");
    let inputs: Vec<_> = robot(1, false)
        .into_iter()
        .filter(|(_, i)| !matches!(i, Input::Image(_)))
        .collect();
    play(&mut source, &inputs);
    // A camera whose mounts were published in a circle: a -> b -> c -> a.
    let id = DAffine3::IDENTITY;
    let circle = ["cam_a", "cam_b", "cam_c", "cam_a"];
    let edges = circle
        .windows(2)
        .map(|w| edge(w[0], w[1], T0, &id))
        .collect();
    source.on_tf(&tf(edges), true);
    assert_eq!(count(&source, "tf/loops"), 1);
    assert!(matches!(source.last_refused(), Some(TfError::Loop { .. })));
    let now = T0 + 1000 * MS;
    for stamp in [T0 + 507 * MS, T0 + 607 * MS] {
        source.on_image(stamp, "cam_b", now);
    }
    source.on_image(T0 + 707 * MS, "camera_optical", now);
    assert_eq!(
        source.take_ready(now).len(),
        1,
        "the robot's camera is fine"
    );
    assert!(source.take_ready(now + DEFAULT_WAIT_NS).is_empty());
    assert_eq!(count(&source, "pose_source/failed"), 2);
    assert!(matches!(
        source.last_given_up(),
        Some(GiveUp::Failed {
            source: TfError::NotConnected { .. },
            ..
        })
    ));
}

#[test]
fn odometry_with_a_static_or_fixed_mount_gives_the_analytic_camera_pose() {
    for mount_kind in [Mount::TfStatic, Mount::Fixed(mount())] {
        let kind = PoseSourceKind::Odometry {
            mount: mount_kind.clone(),
        };
        let mut source = PoseSource::new(PoseSourceConfig::new(kind, None)).unwrap();
        let out = play(&mut source, &robot(2, true));
        assert_eq!(out.len(), 20, "{mount_kind:?}");
        for (_, stamp, pose) in &out {
            // Odometry's own frame, map -> odom on /tf ignored.
            assert_pose(pose, &(odom_base(*stamp) * mount()), "odometry");
        }
        assert_eq!(count(&source, "pose_source/ignored_tf"), 11);
        assert_eq!(count(&source, "tf/inserted"), 2 + 101);
    }
    // Into map, through a static map -> odom.
    let kind = PoseSourceKind::Odometry {
        mount: Mount::TfStatic,
    };
    let mut source = PoseSource::new(PoseSourceConfig::new(kind, Some("map".into()))).unwrap();
    source.on_tf(&tf(vec![edge("map", "odom", T0, &map_odom(T0))]), true);
    let out = play(&mut source, &robot(1, true));
    assert_eq!(out.len(), 10);
    for (_, stamp, pose) in &out {
        assert_pose(pose, &(map_odom(T0) * odom_base(*stamp) * mount()), "map");
    }
}

#[test]
fn without_odometry_images_time_out_and_dynamic_tf_does_not_help() {
    let kind = PoseSourceKind::Odometry {
        mount: Mount::TfStatic,
    };
    let mut source = PoseSource::new(PoseSourceConfig::new(kind, None)).unwrap();
    let inputs: Vec<_> = robot(1, false)
        .into_iter()
        .filter(|(_, i)| !matches!(i, Input::Image(_)))
        .collect();
    play(&mut source, &inputs);
    source.on_image(T0 + 507 * MS, "camera_optical", T0);
    assert!(source.take_ready(T0 + DEFAULT_WAIT_NS).is_empty());
    assert_eq!(
        source.last_given_up(),
        Some(&GiveUp::NoOdometry {
            stamp_ns: T0 + 507 * MS,
            wait_ns: DEFAULT_WAIT_NS
        })
    );
    assert_eq!(count(&source, "pose_source/timed_out"), 1);
    // In tf mode an Odometry changes nothing.
    let mut tf_mode = tf_source("odom");
    tf_mode.on_odometry(&odometry(T0));
    assert_eq!(tf_mode.buffer().frames().count(), 0);
}

#[test]
fn nan_transforms_and_odometry_are_refused_and_the_poses_stay_analytic() {
    let mut inputs = robot(1, false);
    let mut nan = edge(
        "odom",
        "base_link",
        T0 + 310 * MS,
        &odom_base(T0 + 310 * MS),
    );
    nan.transform.rotation.w = f64::NAN;
    inputs.insert(1, (T0, Input::Tf(tf(vec![nan]), false)));
    let mut source = tf_source("map");
    let out = play(&mut source, &inputs);
    assert_eq!(out.len(), 10);
    for (_, stamp, pose) in &out {
        assert_pose(
            pose,
            &(map_odom(*stamp) * odom_base(*stamp) * mount()),
            "nan",
        );
    }
    assert_eq!(count(&source, "tf/invalid"), 1);
    assert!(matches!(
        source.last_refused(),
        Some(TfError::Invalid { .. })
    ));
    // An Odometry with NaN: refused, its frames not taken.
    let kind = PoseSourceKind::Odometry {
        mount: Mount::Fixed(DAffine3::IDENTITY),
    };
    let mut odo = PoseSource::new(PoseSourceConfig::new(kind, None)).unwrap();
    let mut bad = odometry(T0);
    bad.pose.pose.position.x = f64::INFINITY;
    odo.on_odometry(&bad);
    odo.on_image(T0, "camera_optical", T0);
    assert!(odo.take_ready(i64::MAX).is_empty());
    assert_eq!(count(&odo, "tf/invalid"), 1);
    assert!(matches!(
        odo.last_given_up(),
        Some(GiveUp::NoOdometry { .. })
    ));
}

#[test]
fn a_flood_of_stamps_without_tf_stays_bounded() {
    let mut source = tf_source("map");
    let max = DEFAULT_MAX_PENDING;
    for k in 0..100_000i64 {
        // Every tenth with its own frame name: distinct names cost nothing more.
        let frame = match k % 10 {
            0 => format!("cam{k}"),
            _ => "camera_optical".into(),
        };
        source.on_image(T0 + k * MS, &frame, T0 + k * MS);
        if k % 1000 == 0 {
            assert!(source.take_ready(T0 + k * MS).is_empty());
        }
        assert!(source.pending() <= max);
    }
    assert_eq!(source.pending(), max);
    assert_eq!(count(&source, "pose_source/overflow"), 100_000 - max as u64);
    assert_eq!(
        source.last_given_up(),
        Some(&GiveUp::Overflow {
            stamp_ns: T0 + (99_999 - max as i64) * MS,
            max
        })
    );
    assert!(source.take_ready(i64::MAX).is_empty());
    assert_eq!(count(&source, "pose_source/failed"), max as u64);
    assert_eq!(source.pending(), 0);
}

#[test]
fn stamps_and_clocks_at_their_extremes_neither_overflow_nor_panic() {
    let mut config = PoseSourceConfig::new(PoseSourceKind::Tf, Some("map".into()));
    config.buffer.cache_ns = i64::MAX;
    let mut source = PoseSource::new(config).unwrap();
    // A static path: any stamp, 0 included.
    source.on_tf(&tf(vec![edge("map", "cam", T0, &mount())]), true);
    for stamp in [i64::MIN, -1, LATEST, 1, i64::MAX] {
        source.on_image(stamp, "cam", i64::MAX);
    }
    let ready = source.take_ready(i64::MIN);
    let stamps: Vec<_> = ready.iter().map(|(s, _)| *s).collect();
    assert_eq!(stamps, [i64::MIN, -1, LATEST, 1, i64::MAX]);
    assert!(ready.iter().all(|(_, p)| distance(p, &mount()) < 1e-12));
    // A dynamic edge spanning every stamp a Time can hold.
    let first = Time::from_nanos(i64::MIN).to_nanos();
    let last = Time::from_nanos(i64::MAX).to_nanos();
    for (stamp, x) in [(first, -1.0), (last, 1.0)] {
        let a = DAffine3::from_translation(DVec3::X * x);
        source.on_tf(&tf(vec![edge("map", "drone", stamp, &a)]), false);
    }
    let mid = first + (last - first) / 2;
    for (stamp, now) in [(i64::MIN, i64::MIN), (mid, i64::MAX), (i64::MAX, i64::MIN)] {
        source.on_image(stamp, "drone", now);
    }
    let ready = source.take_ready(i64::MIN);
    assert_eq!(ready.len(), 1);
    assert!(ready[0].1.translation.x.abs() < 1e-9);
    // Before the first sample: failed at once; after the last: waits, then times out.
    assert_eq!(count(&source, "pose_source/failed"), 1);
    assert_eq!(source.pending(), 1);
    assert!(source.take_ready(i64::MIN + DEFAULT_WAIT_NS).is_empty());
    assert_eq!(count(&source, "pose_source/timed_out"), 1);
    // An image stamped 0 is tf2's latest time: the newest sample.
    source.on_image(LATEST, "drone", 0);
    assert_eq!(source.take_ready(0)[0].1.translation.x, 1.0);
}

#[test]
fn frame_names_are_checked_and_a_configured_camera_frame_wins() {
    let mut source = tf_source("map");
    source.on_image(T0, "", T0);
    source.on_image(T0, "/", T0);
    source.on_image(T0, &"c".repeat(257), T0);
    assert_eq!(count(&source, "pose_source/failed"), 3);
    assert_eq!(source.pending(), 0);
    assert!(matches!(
        source.last_given_up(),
        Some(GiveUp::Failed {
            source: TfError::NameTooLong { len: 257, max: 256 },
            ..
        })
    ));
    let mut config = PoseSourceConfig::new(PoseSourceKind::Tf, Some("map".into()));
    config.camera_frame = Some("cam".into());
    let mut fixed = PoseSource::new(config).unwrap();
    fixed.on_tf(&tf(vec![edge("map", "cam", T0, &mount())]), true);
    fixed.on_image(T0, "", T0);
    assert_eq!(fixed.take_ready(T0).len(), 1);
}

#[test]
fn configurations_are_checked() {
    let tf_without_world = PoseSourceConfig::new(PoseSourceKind::Tf, None);
    assert_eq!(
        PoseSource::new(tf_without_world).err(),
        Some(PoseSourceError::NoWorldFrame)
    );
    let fixed = |m: DAffine3| {
        let kind = PoseSourceKind::Odometry {
            mount: Mount::Fixed(m),
        };
        PoseSource::new(PoseSourceConfig::new(kind, None))
    };
    let mut nan = mount();
    nan.translation.y = f64::NAN;
    let scaled = DAffine3::from_scale(DVec3::splat(1.01)) * mount();
    let mirrored = DAffine3::from_scale(DVec3::new(1.0, 1.0, -1.0));
    for bad in [nan, scaled, mirrored] {
        assert_eq!(fixed(bad).err(), Some(PoseSourceError::MountNotRigid));
    }
    // Within the tolerance: made exact.
    let near = DAffine3::from_scale(DVec3::splat(1.0 + 1e-7)) * mount();
    let source = fixed(near).unwrap();
    let PoseSourceKind::Odometry {
        mount: Mount::Fixed(m),
    } = &source.config().kind
    else {
        panic!()
    };
    assert!((m.matrix3.determinant() - 1.0).abs() < 1e-12);
    assert!(distance(m, &mount()) < 1e-6);
    // A wait below 0 is 0, a bound of 0 is 1.
    let mut config = PoseSourceConfig::new(PoseSourceKind::Tf, Some("map".into()));
    (config.wait_ns, config.max_pending) = (-5, 0);
    let source = PoseSource::new(config).unwrap();
    assert_eq!(
        (source.config().wait_ns, source.config().max_pending),
        (0, 1)
    );
}
