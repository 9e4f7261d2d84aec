//! Poses from where robots publish them. A generated drive is sent as a robot's graph
//! would publish it: no PoseStamped of the camera, but a `/tf` tree `map -> odom` (static)
//! `-> base_link` (at each frame's stamp) `-> camera_optical` (the mount, static, REP 103's
//! optical axes), and, for `--pose-source odometry`, `nav_msgs/Odometry` of `base_link` in
//! `odom`. The node looks up the left camera at each image's stamp; its bin poses equal the
//! drive's own (PoseStamped) run's within a micrometre, mapped into `odom` for odometry.

use crate::drive_support;

use drive_support::{sgm_config, Collector, Drive, Player, RunningNode};
use glam::{DAffine3, DMat3, DQuat, DVec3};
use node::msg::geometry_msgs::{PoseStamped, PoseWithCovariance};
use node::msg::image::image_from_rgb;
use node::msg::nav_msgs::Odometry;
use node::msg::pose::{affine_from_pose, pose_from_affine};
use node::msg::std_msgs::Header;
use node::msg::tf2_msgs::{world_to, TfMessage};
use node::msg::Message;
use node::service::keys::{TF, TF_STATIC};
use node::service::{Keys, NodeConfig, NodeSummary};
use node::tf::{Mount, PoseSourceConfig, PoseSourceKind};

/// How the drive's poses are sent.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Poses {
    /// PoseStamped of the left camera in the world.
    Stamped,
    /// The `/tf` tree.
    Tf,
    /// Odometry of the body, the mount on `/tf_static`.
    Odometry,
}

/// `map -> odom`: where odometry started, in the map.
pub(crate) fn map_to_odom() -> DAffine3 {
    DAffine3::from_rotation_translation(DQuat::from_rotation_z(0.3), DVec3::new(5.0, -3.0, 0.2))
}

/// `base_link -> camera_optical`: 1.2 m ahead, 1.5 m up, optical axes (z forward = the
/// body's x, x right = the body's -y, y down = the body's -z).
pub(crate) fn mount() -> DAffine3 {
    let optical = DMat3::from_cols(DVec3::NEG_Y, DVec3::NEG_Z, DVec3::X);
    DAffine3::from_mat3_translation(optical, DVec3::new(1.2, 0.0, 1.5))
}

/// A transform `parent -> child` at `stamp_ns`.
pub(crate) fn edge(
    parent: &str,
    child: &str,
    child_to_parent: &DAffine3,
    stamp_ns: i64,
) -> TfMessage {
    let mut t = world_to(child, child_to_parent, stamp_ns);
    t.header.frame_id = parent.into();
    TfMessage {
        transforms: vec![t],
    }
}

/// Runs the drive through a fresh node with its poses sent as `poses`: the summary and the
/// bin poses.
async fn run(tag: &str, drive: &Drive, poses: Poses) -> (NodeSummary, Vec<DAffine3>) {
    let keys = Keys::new(tag);
    let pose_source = match poses {
        Poses::Stamped => None,
        Poses::Tf => Some(PoseSourceConfig::new(
            PoseSourceKind::Tf,
            Some("map".into()),
        )),
        Poses::Odometry => Some(PoseSourceConfig::new(
            PoseSourceKind::Odometry {
                mount: Mount::TfStatic,
            },
            None,
        )),
    };
    let node = RunningNode::start(NodeConfig {
        pose_source,
        ..sgm_config(&keys)
    })
    .await;
    let outputs = Collector::connect(&node, &[keys.bin_pose()]).await;
    let player = Player::connect(&node).await;
    let first = drive.frames[0].0;
    player.camera_infos(&drive.rig, first).await;
    if poses != Poses::Stamped {
        let statics = [
            edge("map", "odom", &map_to_odom(), first),
            edge("base_link", "camera_optical", &mount(), first),
        ];
        for msg in &statics {
            player.put(keys.key(TF_STATIC), msg.encode()).await;
        }
    }
    let body =
        |camera_to_map: &DAffine3| map_to_odom().inverse() * *camera_to_map * mount().inverse();
    for (stamp, frame) in &drive.frames {
        let header = |id: &str| Header::new(*stamp, id);
        match poses {
            Poses::Stamped => {
                let pose: PoseStamped = pose_from_affine(&frame.left_to_world, header("world"));
                player.put(keys.pose(), pose.encode()).await;
            }
            Poses::Tf => {
                let msg = edge("odom", "base_link", &body(&frame.left_to_world), *stamp);
                player.put(keys.key(TF), msg.encode()).await;
            }
            Poses::Odometry => {
                let odom = Odometry {
                    header: header("odom"),
                    child_frame_id: "base_link".into(),
                    pose: PoseWithCovariance {
                        pose: pose_from_affine(&body(&frame.left_to_world), header("odom")).pose,
                        ..PoseWithCovariance::default()
                    },
                    ..Odometry::default()
                };
                player.put(keys.odometry(), odom.encode()).await;
            }
        }
        let left = image_from_rgb(&frame.left, header("camera_optical"));
        player.put(keys.left_image(), left.encode()).await;
        let right = image_from_rgb(&frame.right, header("camera_right_optical"));
        player.put(keys.right_image(), right.encode()).await;
    }
    let opened = drive.bins_opened(8.0);
    assert!(
        outputs.wait_count(&keys.bin_pose(), opened).await,
        "{poses:?}: every bin"
    );
    let summary = node.stop().await;
    let bin_poses = outputs
        .decoded::<PoseStamped>(&keys.bin_pose())
        .iter()
        .map(|p| affine_from_pose(p).expect("a rigid pose"))
        .collect();
    (summary, bin_poses)
}

/// The largest distance between corresponding points 10 m around the two poses' origins.
fn apart(a: &DAffine3, b: &DAffine3) -> f64 {
    [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z]
        .iter()
        .map(|&p| {
            a.transform_point3(10.0 * p)
                .distance(b.transform_point3(10.0 * p))
        })
        .fold(0.0, f64::max)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn poses_from_tf_and_from_odometry_equal_the_drives_own() {
    let drive = Drive::small("pose_sources");
    let frames = drive.frames.len() as u64;
    let (stamped, truth) = run("ps_stamped", &drive, Poses::Stamped).await;
    let (tf, from_tf) = run("ps_tf", &drive, Poses::Tf).await;
    let (odometry, from_odometry) = run("ps_odometry", &drive, Poses::Odometry).await;
    for (name, s) in [("stamped", &stamped), ("tf", &tf), ("odometry", &odometry)] {
        assert_eq!(
            s.bins_published,
            truth.len() as u64,
            "{name}: {:?}",
            s.counters
        );
        assert_eq!(
            s.counters.sum("bad_message/"),
            0,
            "{name}: {:?}",
            s.counters
        );
    }
    for s in [&tf, &odometry] {
        assert_eq!(
            s.counters.get("pose_source/ready"),
            frames,
            "{:?}",
            s.counters
        );
        assert_eq!(s.counters.get("pose_source/timed_out"), 0);
        assert_eq!(s.counters.get("pose_source/failed"), 0);
    }
    let in_odom = map_to_odom().inverse();
    let mut worst: f64 = 0.0;
    for ((t, a), b) in truth.iter().zip(&from_tf).zip(&from_odometry) {
        worst = worst.max(apart(t, a)).max(apart(&(in_odom * *t), b));
    }
    println!("bin poses from /tf and odometry against PoseStamped: {worst:.2e} m apart at most");
    assert!(worst < 1e-6, "{worst}");
}
