//! The seeds of the robot-side pose sources: `nav_msgs/Odometry` and `nav_msgs/Path`
//! payloads, and `/tf` + `/tf_static` streams in the `tf_buffer` entry's input form (parts
//! of a flag byte, 1 for `/tf_static`, then a `TFMessage`).

use glam::{DAffine3, DMat3, DQuat, DVec3};
use node::msg::geometry_msgs::{
    PoseStamped, TransformStamped, Twist, TwistWithCovariance, Vector3,
};
use node::msg::nav_msgs::{Odometry, Path};
use node::msg::pose::pose_from_affine;
use node::msg::std_msgs::Header;
use node::msg::tf2_msgs::{world_to, TfMessage};
use node::msg::Message;
use node::untrusted_input::join_frames;

use super::{Seeds, STAMP};

/// 100 ms, a 10 Hz odometry.
const PERIOD: i64 = 100_000_000;

/// Writes the seeds of `cdr_odometry`, `cdr_path` and `tf_buffer`; `pose` is a pose far from
/// the origin.
pub fn write(seeds: &Seeds, pose: DAffine3) -> anyhow::Result<()> {
    seeds.put("cdr_odometry", "far", &odometry(pose).encode())?;
    seeds.put("cdr_odometry", "default", &Odometry::default().encode())?;
    let path = Path {
        header: Header::new(STAMP, "map"),
        poses: (0..3).map(|k| body_pose(pose, k)).collect(),
    };
    seeds.put("cdr_path", "three", &path.encode())?;
    seeds.put("cdr_path", "empty", &Path::default().encode())?;
    seeds.put("tf_buffer", "robot", &robot_stream(pose))?;
    seeds.put("tf_buffer", "tangled", &tangled_stream())?;
    Ok(())
}

/// The body's pose at sample `k` in `odom`: `pose`, then 1.5 m/s ahead, yawing.
fn body(pose: DAffine3, k: i64) -> DAffine3 {
    let s = k as f64;
    pose * DAffine3::from_rotation_translation(
        DQuat::from_rotation_z(0.05 * s),
        DVec3::new(0.15 * s, 0.0, 0.0),
    )
}

fn body_pose(pose: DAffine3, k: i64) -> PoseStamped {
    pose_from_affine(&body(pose, k), Header::new(STAMP + k * PERIOD, "map"))
}

/// An Odometry of `base_link` in `odom` at `pose`, moving, with covariances.
fn odometry(pose: DAffine3) -> Odometry {
    let mut msg = Odometry {
        header: Header::new(STAMP, "odom"),
        child_frame_id: "base_link".into(),
        ..Odometry::default()
    };
    msg.pose.pose = pose_from_affine(&pose, Header::default()).pose;
    msg.pose.covariance = std::array::from_fn(|i| if i % 7 == 0 { 0.01 } else { 0.0 });
    msg.twist = TwistWithCovariance {
        twist: Twist {
            linear: Vector3 {
                x: 1.5,
                y: 0.0,
                z: 0.0,
            },
            angular: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 0.5,
            },
        },
        covariance: std::array::from_fn(|i| if i % 7 == 0 { 0.1 } else { 0.0 }),
    };
    msg
}

/// The transform `parent` -> `child` (the pose of `child` in `parent`) at `stamp`.
fn edge(parent: &str, child: &str, pose: &DAffine3, stamp: i64) -> TransformStamped {
    let mut t = world_to(child, pose, stamp);
    t.header.frame_id = parent.into();
    t
}

/// One part of the `tf_buffer` input: the flag byte, then the message.
fn part(is_static: bool, transforms: Vec<TransformStamped>) -> Vec<u8> {
    let mut bytes = vec![is_static as u8];
    bytes.extend(TfMessage { transforms }.encode());
    bytes
}

/// A robot's tree: world -> odom, base_link -> camera_link -> camera_optical on
/// `/tf_static`, then odom -> base_link at 10 Hz on `/tf`, two samples out of order.
fn robot_stream(pose: DAffine3) -> Vec<u8> {
    let optical = DAffine3::from_mat3(DMat3::from_cols(
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(0.0, 0.0, -1.0),
        DVec3::new(1.0, 0.0, 0.0),
    ));
    let mount = DAffine3::from_rotation_translation(
        DQuat::from_rotation_y(0.1),
        DVec3::new(0.3, -0.06, 1.2),
    );
    let statics = part(
        true,
        vec![
            edge("world", "odom", &pose, STAMP),
            edge("base_link", "camera_link", &mount, STAMP),
            edge("camera_link", "camera_optical", &optical, STAMP),
        ],
    );
    let mut parts = vec![statics];
    for k in [0, 1, 3, 2, 4] {
        let body = body(DAffine3::IDENTITY, k);
        parts.push(part(
            false,
            vec![edge("odom", "base_link", &body, STAMP + k * PERIOD)],
        ));
    }
    let refs: Vec<&[u8]> = parts.iter().map(Vec::as_slice).collect();
    join_frames(&refs)
}

/// A stream that meets the buffer's rules: a transform that would close a loop, a second
/// parent (older, then newer), a repeated stamp, one older than the cache, and a dynamic
/// transform replacing a static one.
fn tangled_stream() -> Vec<u8> {
    let step = DAffine3::from_translation(DVec3::X);
    let parts = [
        part(
            true,
            vec![edge("a", "b", &step, STAMP), edge("b", "c", &step, STAMP)],
        ),
        part(true, vec![edge("c", "a", &step, STAMP)]),
        part(
            false,
            vec![
                edge("a", "d", &step, STAMP),
                edge("a", "d", &step, STAMP + PERIOD),
            ],
        ),
        part(
            false,
            vec![
                edge("c", "d", &step, STAMP),
                edge("c", "d", &step, STAMP + 2 * PERIOD),
            ],
        ),
        part(false, vec![edge("c", "d", &step, STAMP + 2 * PERIOD)]),
        part(false, vec![edge("c", "d", &step, STAMP - 20_000_000_000)]),
        part(false, vec![edge("a", "b", &step, STAMP + 3 * PERIOD)]),
    ];
    let refs: Vec<&[u8]> = parts.iter().map(Vec::as_slice).collect();
    join_frames(&refs)
}
