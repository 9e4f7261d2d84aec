//! Odometry and Path: round trips, every truncation, claimed lengths past the payload, and
//! the checked reading of an Odometry's pose.

use glam::{DQuat, DVec3};

use super::*;
use crate::msg::geometry_msgs::{Point, Pose, Quaternion, Twist, Vector3};
use crate::msg::std_msgs::Time;

/// An Odometry of `base_link` in `odom` 100 km out, every covariance entry distinct.
fn odometry() -> Odometry {
    let q = DQuat::from_axis_angle(DVec3::new(0.3, -1.0, 0.2).normalize(), 1.1);
    Odometry {
        header: Header::new(1_700_000_000_123_456_789, "odom"),
        child_frame_id: "base_link".into(),
        pose: PoseWithCovariance {
            pose: Pose {
                position: Point {
                    x: 100_000.125,
                    y: -250_000.5,
                    z: 31.25,
                },
                orientation: Quaternion {
                    x: q.x,
                    y: q.y,
                    z: q.z,
                    w: q.w,
                },
            },
            covariance: std::array::from_fn(|i| i as f64 * 0.5 - 3.0),
        },
        twist: TwistWithCovariance {
            twist: Twist {
                linear: Vector3 {
                    x: 1.5,
                    y: -0.25,
                    z: 0.0,
                },
                angular: Vector3 {
                    x: 0.0,
                    y: 0.125,
                    z: -2.0,
                },
            },
            covariance: std::array::from_fn(|i| 1e-3 * i as f64),
        },
    }
}

/// A path of `n` poses along x, one per 0.1 s.
fn path(n: usize) -> Path {
    Path {
        header: Header::new(5_000_000_000, "map"),
        poses: (0..n)
            .map(|i| PoseStamped {
                header: Header::new(4_000_000_000 + i as i64 * 100_000_000, "map"),
                pose: Pose {
                    position: Point {
                        x: i as f64,
                        y: 0.5,
                        z: -1.0,
                    },
                    orientation: Quaternion::default(),
                },
            })
            .collect(),
    }
}

#[test]
fn odometry_round_trips_field_for_field() {
    let msg = odometry();
    let bytes = msg.encode();
    // Stamp 8, "odom" 4 + 5 (+3 pad), "base_link" 4 + 10 (+6 pad to the f64s), then
    // 7 + 36 + 6 + 36 f64.
    assert_eq!(bytes.len(), 4 + 8 + 12 + 20 + (7 + 36 + 6 + 36) * 8);
    let back = Odometry::decode(&bytes).unwrap();
    assert_eq!(back, msg);
    assert_eq!(back.pose.covariance[35], 14.5);
    assert_eq!(back.twist.twist.angular.z, -2.0);
}

#[test]
fn path_round_trips_and_an_empty_path_is_valid() {
    for n in [0, 1, 3] {
        let msg = path(n);
        assert_eq!(Path::decode(&msg.encode()).unwrap(), msg, "{n} poses");
    }
    let back = Path::decode(&path(3).encode()).unwrap();
    assert_eq!(back.poses[2].header.stamp.to_nanos(), 4_200_000_000);
    assert_eq!(back.poses[2].pose.position.x, 2.0);
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = odometry().encode();
    for cut in 0..bytes.len() {
        assert!(
            Odometry::decode(&bytes[..cut]).is_err(),
            "odometry cut at {cut}"
        );
    }
    let bytes = path(3).encode();
    for cut in 0..bytes.len() {
        assert!(Path::decode(&bytes[..cut]).is_err(), "path cut at {cut}");
    }
}

#[test]
fn a_path_claiming_four_billion_poses_in_twenty_bytes_is_refused() {
    // Header: stamp 8, frame_id "" (length 0), then the count 0xffff_ffff and 4 bytes.
    let mut bytes = vec![0, 1, 0, 0];
    bytes.extend_from_slice(&[0; 8]);
    bytes.extend_from_slice(&0u32.to_le_bytes());
    bytes.extend_from_slice(&u32::MAX.to_le_bytes());
    bytes.extend_from_slice(&[7; 4]);
    assert_eq!(bytes.len(), 24);
    let err = Path::decode(&bytes).unwrap_err();
    assert_eq!(
        err,
        DecodeError::LengthPastEnd {
            what: "poses",
            at: 16,
            count: u32::MAX,
            need: u32::MAX as u64 * POSE_STAMPED_MIN_BYTES as u64,
            left: 4,
        }
    );
    // One pose claimed where there is room for none: refused before reading it.
    let mut one = path(0).encode();
    let at = one.len() - 4;
    one[at..].copy_from_slice(&1u32.to_le_bytes());
    one.extend_from_slice(&[0; POSE_STAMPED_MIN_BYTES - 1]);
    assert!(matches!(
        Path::decode(&one),
        Err(DecodeError::LengthPastEnd { count: 1, .. })
    ));
}

#[test]
fn garbage_is_a_typed_error() {
    assert_eq!(
        Odometry::decode(&[0, 2, 0, 0, 1, 2, 3]),
        Err(DecodeError::UnsupportedEncapsulation(0, 2))
    );
    assert_eq!(Path::decode(&[0, 1]), Err(DecodeError::NoHeader { len: 2 }));
    // A frame_id that claims more bytes than there are.
    let mut bytes = odometry().encode();
    bytes[12..16].copy_from_slice(&0x7fff_ffffu32.to_le_bytes());
    assert!(matches!(
        Odometry::decode(&bytes),
        Err(DecodeError::LengthPastEnd {
            what: "header.frame_id",
            ..
        })
    ));
    // A frame_id whose last byte is not NUL.
    let mut bytes = odometry().encode();
    bytes[12 + 4 + 4] = b'x';
    assert!(matches!(
        Odometry::decode(&bytes),
        Err(DecodeError::MissingNul { .. })
    ));
}

#[test]
fn the_odometry_pose_is_the_rigid_body_to_parent_transform() {
    let msg = odometry();
    let pose = odometry_pose(&msg).unwrap();
    assert_eq!(pose.stamp_ns, 1_700_000_000_123_456_789);
    assert_eq!(
        (pose.frame_id.as_str(), pose.child_frame_id.as_str()),
        ("odom", "base_link")
    );
    let o = msg.pose.pose.orientation;
    let q = DQuat::from_xyzw(o.x, o.y, o.z, o.w);
    let body_point = DVec3::new(1.0, 2.0, -3.0);
    let want = q * body_point + DVec3::new(100_000.125, -250_000.5, 31.25);
    let got = pose.child_to_parent.transform_point3(body_point);
    assert!((got - want).length() < 1e-9, "{got} vs {want}");
    // Negative stamps floor as ROS does.
    let mut before_epoch = msg.clone();
    before_epoch.header.stamp = Time {
        sec: -1,
        nanosec: 999_999_999,
    };
    assert_eq!(odometry_pose(&before_epoch).unwrap().stamp_ns, -1);
}

#[test]
fn a_non_finite_or_non_unit_odometry_pose_is_refused() {
    let mut nan = odometry();
    nan.pose.pose.orientation.w = f64::NAN;
    assert_eq!(
        odometry_pose(&nan),
        Err(ConvertError::NonFinite("orientation.w"))
    );
    let mut inf = odometry();
    inf.pose.pose.position.y = f64::NEG_INFINITY;
    assert_eq!(
        odometry_pose(&inf),
        Err(ConvertError::NonFinite("position.y"))
    );
    let mut zero = odometry();
    zero.pose.pose.orientation = Quaternion {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 0.0,
    };
    assert!(matches!(
        odometry_pose(&zero),
        Err(ConvertError::NonUnitQuaternion { norm, .. }) if norm == 0.0
    ));
    // Within the tolerance the quaternion is normalised: the rotation stays orthonormal.
    let mut near = odometry();
    near.pose.pose.orientation.w *= 1.0 + 5e-6;
    let m = odometry_pose(&near).unwrap().child_to_parent.matrix3;
    assert!((m.determinant() - 1.0).abs() < 1e-12);
    // Covariance and twist values are carried, not checked.
    let mut nan_twist = odometry();
    nan_twist.twist.covariance[0] = f64::NAN;
    assert!(odometry_pose(&nan_twist).is_ok());
}
