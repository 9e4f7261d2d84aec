//! An Odometry and the camera's mount: the camera's pose analytically, the mount from the
//! buffer's static part, and the Odometry as a tf edge.

use glam::{DAffine3, DQuat, DVec3};

use super::*;
use crate::msg::geometry_msgs::{Point, Pose, Quaternion};
use crate::msg::std_msgs::Header;
use crate::msg::ConvertError;
use crate::tf::tests::{optical, transform};
use crate::tf::{TfBuffer, TfConfig};

const STAMP: i64 = 1_700_000_000_700_000_000;

/// `base_link` in `odom`, 100 km out, yawed.
fn body() -> (DQuat, DVec3) {
    (
        DQuat::from_rotation_z(2.5),
        DVec3::new(100_000.25, -3.5, 0.125),
    )
}

fn odometry() -> Odometry {
    let (q, t) = body();
    let mut odometry = Odometry {
        header: Header::new(STAMP, "odom"),
        child_frame_id: "base_link".into(),
        ..Odometry::default()
    };
    odometry.pose.pose = Pose {
        position: Point {
            x: t.x,
            y: t.y,
            z: t.z,
        },
        orientation: Quaternion {
            x: q.x,
            y: q.y,
            z: q.z,
            w: q.w,
        },
    };
    odometry
}

/// A static buffer: base_link -> camera_link (0.3 m ahead, 1.2 m up, pitched) ->
/// camera_optical (REP 103).
fn mounts() -> TfBuffer {
    let mut tf = TfBuffer::new(TfConfig::default());
    let edges = [
        (
            "base_link",
            "camera_link",
            DQuat::from_rotation_y(0.1),
            DVec3::new(0.3, 0.0, 1.2),
        ),
        ("camera_link", "camera_optical", optical(), DVec3::ZERO),
    ];
    for (parent, child, q, t) in edges {
        let transform = transform(parent, child, STAMP, q, t);
        tf.insert(&transform, true).unwrap();
    }
    tf
}

#[test]
fn the_camera_pose_is_the_body_pose_after_the_mount() {
    let mount = mounts()
        .lookup_static("base_link", "camera_optical")
        .unwrap();
    let camera = camera_pose_from_odometry(&odometry(), &mount).unwrap();
    assert_eq!((camera.stamp_ns, camera.frame_id.as_str()), (STAMP, "odom"));
    // 10 m ahead of the camera: along the pitched camera_link's x, from 1.2 m above the body,
    // then yawed into odom.
    let ahead = camera
        .camera_to_parent
        .transform_point3(DVec3::new(0.0, 0.0, 10.0));
    let in_body =
        DVec3::new(0.3, 0.0, 1.2) + DQuat::from_rotation_y(0.1) * DVec3::new(10.0, 0.0, 0.0);
    let (q, t) = body();
    let want = q * in_body + t;
    assert!((ahead - want).length() < 1e-9, "{ahead} vs {want}");
}

#[test]
fn the_odometry_as_a_tf_edge_gives_the_same_pose() {
    let mut tf = mounts();
    tf.insert(&odometry_transform(&odometry()), false).unwrap();
    let mount = tf.lookup_static("base_link", "camera_optical").unwrap();
    let camera = camera_pose_from_odometry(&odometry(), &mount).unwrap();
    let got = tf.lookup("odom", "camera_optical", STAMP).unwrap();
    for p in [DVec3::ZERO, DVec3::new(1.0, -2.0, 30.0)] {
        let d = got.transform_point3(p) - camera.camera_to_parent.transform_point3(p);
        assert!(d.length() < 1e-9, "{d}");
    }
    let (q, t) = body();
    let edge = tf.lookup("odom", "base_link", STAMP).unwrap();
    assert!((edge.translation - t).length() < 1e-12);
    for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
        assert!((edge.matrix3 * axis - q * axis).length() < 1e-12);
    }
}

#[test]
fn a_bad_odometry_pose_is_refused_with_its_reason() {
    let mut odometry = odometry();
    odometry.pose.pose.orientation.w = f64::NAN;
    assert_eq!(
        camera_pose_from_odometry(&odometry, &DAffine3::IDENTITY),
        Err(ConvertError::NonFinite("orientation.w"))
    );
    odometry.pose.pose.orientation = Quaternion {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 0.0,
    };
    assert!(matches!(
        camera_pose_from_odometry(&odometry, &DAffine3::IDENTITY),
        Err(ConvertError::NonUnitQuaternion { .. })
    ));
    // The buffer refuses the same pose as an edge.
    let mut tf = TfBuffer::new(TfConfig::default());
    assert!(tf.insert(&odometry_transform(&odometry), false).is_err());
}
