//! One message of each type with known values, shared by the `msg_*` tests (each test uses
//! a part of it, hence the `dead_code` allowance).
#![allow(dead_code)]

pub mod values;

use glam::{DAffine3, DQuat, DVec3, Quat, Vec3};
use node::msg::gaussians::cloud_from_gaussians;
use node::msg::geometry_msgs::PoseStamped;
use node::msg::image::camera_info;
use node::msg::latency::{BinLatency, Counter, Diagnostics};
use node::msg::map_update::MapUpdate;
use node::msg::nav_msgs::{Odometry, Path};
use node::msg::pose::pose_from_affine;
use node::msg::sensor_msgs::{CameraInfo, Image, PointCloud2};
use node::msg::std_msgs::Header;
use node::msg::tf2_msgs::{world_to, TfMessage};
use node::msg::{DecodeError, Message};
use renderer::{Gaussian, GaussianSet, Intrinsics};

/// A world position 100 km out, where f32 keeps only ~8 mm.
pub const FAR: DVec3 = DVec3::new(100_000.125, -250_000.5, 31.25);

/// The samples.
pub struct Samples {
    pub image: Image,
    pub camera_info: CameraInfo,
    pub pose: PoseStamped,
    pub cloud: PointCloud2,
    pub world_cloud: PointCloud2,
    pub latency: BinLatency,
    pub diagnostics: Diagnostics,
    pub map_update: MapUpdate,
    pub tf: TfMessage,
    pub odometry: Odometry,
    pub path: Path,
}

/// Three Gaussians with distinct values in every channel.
pub fn gaussians() -> GaussianSet {
    let mut set = GaussianSet::default();
    for i in 0..3 {
        let f = i as f32;
        set.push(Gaussian {
            mean: Vec3::new(1.501 + f, -2.253 * f, 10.0 + 0.507 * f),
            log_scale: Vec3::new(-3.0 + 0.1 * f, -2.5, -4.0 + f),
            rotation: Quat::from_rotation_y(0.3 * f + 0.1),
            opacity: 0.2 + 0.3 * f,
            color: Vec3::new(0.1 * f, 0.5, 0.9 - 0.2 * f),
            confidence: 0.25 + 0.25 * f,
        });
    }
    set
}

/// The right camera's pose 100 km out, a rotation about a tilted axis.
pub fn far_pose() -> DAffine3 {
    let q = DQuat::from_axis_angle(DVec3::new(0.2, 1.0, -0.1).normalize(), 0.7);
    DAffine3::from_rotation_translation(q, FAR)
}

pub fn samples() -> Samples {
    let k = Intrinsics {
        fx: 552.5,
        fy: 551.25,
        cx: 682.0,
        cy: 238.75,
        width: 1408,
        height: 376,
    };
    let stamp = 1_700_000_000_123_456_789;
    Samples {
        image: Image {
            header: Header::new(stamp, "cam_left"),
            height: 2,
            width: 3,
            encoding: "rgb8".to_owned(),
            is_bigendian: 0,
            step: 10,
            data: (0..20).map(|i| (i * 13) as u8).collect(),
        },
        camera_info: camera_info(&k, 0.6, Header::new(stamp, "cam_right")),
        pose: pose_from_affine(&far_pose(), Header::new(stamp, "world")),
        cloud: cloud_from_gaussians(&gaussians(), Header::new(stamp, "bin_7"), None)
            .expect("lengths agree"),
        world_cloud: cloud_from_gaussians(&gaussians(), Header::new(stamp, "world"), Some(FAR))
            .expect("lengths agree"),
        latency: BinLatency {
            bin_id: 7,
            first_frame_arrival_ns: stamp,
            bin_close_ns: stamp + 1_000_000_000,
            model_start_ns: stamp + 1_010_000_000,
            model_end_ns: stamp + 1_250_000_000,
            render_end_ns: stamp + 1_300_000_000,
            publish_ns: stamp + 1_305_000_000,
            queue_depth: 2,
            drops: 1,
            bad_messages: u64::MAX - 5,
            check_verdict: 2,
            check_action: 3,
            fallback_verdict: 1,
            check_samples: 1023,
            check_score: 0.125,
            fallback_score: 0.9375,
            base_end_ns: stamp + 1_100_000_000,
            pseudo_render_end_ns: stamp + 1_120_000_000,
            enhance_end_ns: stamp + 1_150_000_000,
            plus_end_ns: stamp + 1_240_000_000,
            fuse_end_ns: stamp + 1_245_000_000,
            operating_point: "tiny-scale0.5".into(),
            map_fused_ns: stamp + 1_262_000_000,
        },
        diagnostics: Diagnostics {
            stamp_ns: -42,
            counters: vec![
                Counter {
                    kind: "bad_message/left_image".to_owned(),
                    count: 3,
                },
                Counter {
                    kind: "drop/worker_queue".to_owned(),
                    count: 1 << 40,
                },
            ],
        },
        map_update: MapUpdate {
            header: Header::new(stamp, "world"),
            sequence: 12,
            snapshot: false,
            bin_id: 7,
            ids: vec![40, 41, 1 << 50],
            source_bins: vec![7, 7, 6],
            removed_ids: vec![3, u64::MAX],
            gaussians: cloud_from_gaussians(&gaussians(), Header::new(stamp, "world"), Some(FAR))
                .expect("lengths agree"),
        },
        tf: TfMessage {
            transforms: vec![
                world_to("bin_7", &far_pose(), stamp),
                world_to("cam_left", &DAffine3::IDENTITY, -1),
            ],
        },
        odometry: odometry(stamp),
        path: Path {
            header: Header::new(stamp, "map"),
            poses: (0..3)
                .map(|i| {
                    let step = DAffine3::from_translation(DVec3::new(0.5 * i as f64, 0.0, 0.0));
                    pose_from_affine(&(far_pose() * step), Header::new(stamp + i, "map"))
                })
                .collect(),
        },
    }
}

/// `base_link` in `odom` at the far pose, moving, every covariance entry distinct.
fn odometry(stamp: i64) -> Odometry {
    let mut msg = Odometry {
        header: Header::new(stamp, "odom"),
        child_frame_id: "base_link".to_owned(),
        ..Odometry::default()
    };
    msg.pose.pose = pose_from_affine(&far_pose(), Header::default()).pose;
    msg.pose.covariance = std::array::from_fn(|i| 1e-3 * (i + 1) as f64);
    msg.twist.twist.linear.x = 1.5;
    msg.twist.twist.angular.z = -0.25;
    msg.twist.covariance = std::array::from_fn(|i| -1e-2 * i as f64);
    msg
}

/// A decoder that reports only whether it succeeded.
pub type Decoder = fn(&[u8]) -> Result<(), DecodeError>;

fn decoder<M: Message>() -> Decoder {
    |b| M::decode(b).map(drop)
}

/// Every top-level sample as (ROS type name, payload, its decoder).
pub fn encoded() -> Vec<(&'static str, Vec<u8>, Decoder)> {
    let s = samples();
    vec![
        (Image::KIND.ros_name(), s.image.encode(), decoder::<Image>()),
        (
            CameraInfo::KIND.ros_name(),
            s.camera_info.encode(),
            decoder::<CameraInfo>(),
        ),
        (
            PoseStamped::KIND.ros_name(),
            s.pose.encode(),
            decoder::<PoseStamped>(),
        ),
        (
            PointCloud2::KIND.ros_name(),
            s.cloud.encode(),
            decoder::<PointCloud2>(),
        ),
        (
            PointCloud2::KIND.ros_name(),
            s.world_cloud.encode(),
            decoder::<PointCloud2>(),
        ),
        (
            BinLatency::KIND.ros_name(),
            s.latency.encode(),
            decoder::<BinLatency>(),
        ),
        (
            Diagnostics::KIND.ros_name(),
            s.diagnostics.encode(),
            decoder::<Diagnostics>(),
        ),
        (
            MapUpdate::KIND.ros_name(),
            s.map_update.encode(),
            decoder::<MapUpdate>(),
        ),
        (
            TfMessage::KIND.ros_name(),
            s.tf.encode(),
            decoder::<TfMessage>(),
        ),
        (
            Odometry::KIND.ros_name(),
            s.odometry.encode(),
            decoder::<Odometry>(),
        ),
        (Path::KIND.ros_name(), s.path.encode(), decoder::<Path>()),
    ]
}
