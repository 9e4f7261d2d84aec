//! Poses from where robots publish them. A generated drive is sent as a robot's graph
//! would publish it: no PoseStamped of the camera, but a `/tf` tree `map -> odom` (static)
//! `-> base_link` (at each frame's stamp) `-> camera_optical` (the mount, static, REP 103's
//! optical axes), and, for `--pose-source odometry`, `nav_msgs/Odometry` of `base_link` in
//! `odom`. The node looks up the left camera at each image's stamp; its bins open on the
//! same frames as the drive's own (PoseStamped) run's, their poses equal the drive's within
//! a micrometre (mapped into `odom` for odometry), and the outputs are in the pose source's
//! world frame (`map`, `odom`). A mount latched on `/tf_static` before the node started (a
//! cached advanced publisher, as the ROS 2 bridge routes a `TRANSIENT_LOCAL` writer) still
//! reaches it.

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
use node::service::{NodeConfig, NodeSummary};
use node::tf::{Mount, PoseSourceConfig, PoseSourceKind};
use node::transport::keys::{TF, TF_STATIC};
use node::transport::Keys;
use node::transport::TransportConfig;
use zenoh_ext::{AdvancedPublisherBuilderExt, CacheConfig};

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

/// Added to the drive's stamps (which start at 0): a robot's clock. A stamp of 0 is tf2's
/// `TimePointZero`, the latest transform when the lookup happens, which depends on when
/// `/tf` (a subscriber of its own) arrives beside the images.
pub(crate) const CLOCK_NS: i64 = 1_700_000_000_000_000_000;

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

/// A bin's pose as published: its stamp, frame and pose.
type BinPose = (i64, String, DAffine3);

/// Runs the drive through a fresh node with its poses sent as `poses`: the summary and the
/// bin poses.
async fn run(tag: &str, drive: &Drive, poses: Poses) -> (NodeSummary, Vec<BinPose>) {
    let keys = Keys::new(tag);
    let (pose_source, world) = match poses {
        Poses::Stamped => (None, "world"),
        Poses::Tf => (
            Some(PoseSourceConfig::new(
                PoseSourceKind::Tf,
                Some("map".into()),
            )),
            "map",
        ),
        Poses::Odometry => (
            Some(PoseSourceConfig::new(
                PoseSourceKind::Odometry {
                    mount: Mount::TfStatic,
                },
                None,
            )),
            "odom",
        ),
    };
    let node = RunningNode::start(NodeConfig {
        pose_source,
        world_frame: world.into(),
        ..sgm_config(&keys)
    })
    .await;
    let outputs = Collector::connect(&node, &[keys.bin_pose()]).await;
    let player = Player::connect(&node).await;
    let first = drive.frames[0].0 + CLOCK_NS;
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
        let stamp = &(stamp + CLOCK_NS);
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
        .map(|p| {
            let pose = affine_from_pose(p).expect("a rigid pose");
            (p.header.stamp.to_nanos(), p.header.frame_id.clone(), pose)
        })
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
    // The same frames open the bins: a frame lost on the way would show here, with the
    // counters that say where.
    let stamps = |poses: &[BinPose]| poses.iter().map(|p| p.0).collect::<Vec<_>>();
    for (name, s, poses) in [
        ("tf", &tf, &from_tf),
        ("odometry", &odometry, &from_odometry),
    ] {
        assert_eq!(
            stamps(poses),
            stamps(&truth),
            "{name}: bins opened on other frames; {:?} against {:?}",
            s.counters,
            stamped.counters
        );
    }
    for (poses, world) in [
        (&truth, "world"),
        (&from_tf, "map"),
        (&from_odometry, "odom"),
    ] {
        assert!(poses.iter().all(|p| p.1 == world), "{world}: {poses:?}");
    }
    let in_odom = map_to_odom().inverse();
    let mut worst: f64 = 0.0;
    for ((t, a), b) in truth.iter().zip(&from_tf).zip(&from_odometry) {
        worst = worst
            .max(apart(&t.2, &a.2))
            .max(apart(&(in_odom * t.2), &b.2));
    }
    println!("bin poses from /tf and odometry against PoseStamped: {worst:.2e} m apart at most");
    assert!(worst < 1e-6, "{worst}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_mount_latched_before_the_node_started_reaches_it() {
    let drive = Drive::small("pose_latched");
    let keys = Keys::new("ps_latched");
    // The robot's side: a session of its own, and `/tf_static` sent once, before the node
    // exists, through a cached publisher (what the bridge makes of a TRANSIENT_LOCAL
    // writer). A plain put would reach no one: nothing subscribed yet.
    let robot_endpoint = format!("tcp/127.0.0.1:{}", drive_support::free_port());
    // Timestamps on, as the bridge has them: a cached publisher orders by them.
    let mut config = TransportConfig {
        listen: vec![robot_endpoint.clone()],
        ..TransportConfig::default()
    }
    .zenoh_config()
    .expect("a config");
    config
        .insert_json5("timestamping/enabled", "true")
        .expect("timestamping");
    let robot = zenoh::open(config).await.expect("the robot's session");
    let statics = robot
        .declare_publisher(keys.key(TF_STATIC))
        .cache(CacheConfig::default().max_samples(8))
        .publisher_detection()
        .await
        .expect("a cached publisher");
    let first = drive.frames[0].0 + CLOCK_NS;
    for msg in [
        edge("map", "odom", &map_to_odom(), first),
        edge("base_link", "camera_optical", &mount(), first),
    ] {
        statics.put(msg.encode()).await.expect("put");
    }
    let mut config = NodeConfig {
        pose_source: Some(PoseSourceConfig::new(
            PoseSourceKind::Tf,
            Some("map".into()),
        )),
        world_frame: "map".into(),
        ..sgm_config(&keys)
    };
    config.transport.connect = vec![robot_endpoint];
    let node = RunningNode::start(config).await;
    let outputs = Collector::connect(&node, &[keys.bin_pose()]).await;
    let player = Player::connect(&node).await;
    player.camera_infos(&drive.rig, first).await;
    let body =
        |camera_to_map: &DAffine3| map_to_odom().inverse() * *camera_to_map * mount().inverse();
    for (stamp, frame) in &drive.frames {
        let stamp = &(stamp + CLOCK_NS);
        let header = |id: &str| Header::new(*stamp, id);
        let msg = edge("odom", "base_link", &body(&frame.left_to_world), *stamp);
        player.put(keys.key(TF), msg.encode()).await;
        let left = image_from_rgb(&frame.left, header("camera_optical"));
        player.put(keys.left_image(), left.encode()).await;
        let right = image_from_rgb(&frame.right, header("camera_right_optical"));
        player.put(keys.right_image(), right.encode()).await;
    }
    let opened = drive.bins_opened(8.0);
    let all = outputs.wait_count(&keys.bin_pose(), opened).await;
    let summary = node.stop().await;
    let c = &summary.counters;
    assert!(all, "{} of {opened} bins: {c:?}", summary.bins_published);
    assert_eq!(
        c.get("pose_source/ready"),
        drive.frames.len() as u64,
        "{c:?}"
    );
    assert_eq!(
        c.get("pose_source/failed") + c.get("pose_source/timed_out"),
        0
    );
    drop(statics);
    robot.close().await.expect("the robot's session closes");
}
