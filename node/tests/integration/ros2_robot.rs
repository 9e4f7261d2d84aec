//! A robot's graph through real ROS 2: an rclpy node (Jazzy's wheels, Fast DDS) publishes a
//! generated drive as a robot does, JPEG `CompressedImage` pairs on the `compressed`
//! transport, the camera infos, the `/tf` + `/tf_static` tree `map -> odom -> base_link ->
//! camera_optical` and `nav_msgs/Odometry`, through the zenoh ROS 2 bridge (as
//! `ros2_bridge.rs` runs it, loopback only) to a node on `--pose-source tf`. Every bin comes
//! out, each at the pose of the frame that opened it in the drive.

use crate::drive_support;
use crate::node_pose_sources::{edge, map_to_odom, mount, CLOCK_NS};
use crate::python_support;
use crate::ros2_bridge::{bridge_drive, rclpy_node, start_bridge, Running};

use drive_support::{sgm_config, Collector, Drive, RunningNode};
use model::frame::Rgb8Image;
use node::bag::BagWriter;
use node::clients::channel_of;
use node::msg::compressed::{compressed_image, Compression};
use node::msg::geometry_msgs::{PoseStamped, PoseWithCovariance};
use node::msg::image::camera_info;
use node::msg::nav_msgs::Odometry;
use node::msg::pose::{affine_from_pose, pose_from_affine};
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::service::NodeConfig;
use node::tf::{PoseSourceConfig, PoseSourceKind};
use node::transport::keys::{self, Topic};
use node::transport::Keys;
use serde_json::Value;

/// The drive as the robot publishes it, on the node's channel names (`/tf` absolute).
fn write_robot_inputs(drive: &Drive, keys: &Keys, path: &std::path::Path) {
    let mut bag = BagWriter::create(path).unwrap();
    let mut put = |topic: Topic, t: i64, payload: Vec<u8>| {
        bag.write(&channel_of(keys, topic), t as u64, t as u64, 1, &payload)
            .unwrap();
    };
    let rig = &drive.rig;
    let first = drive.frames[0].0 + CLOCK_NS;
    put(
        keys::TF_STATIC,
        first,
        edge("map", "odom", &map_to_odom(), first).encode(),
    );
    put(
        keys::TF_STATIC,
        first,
        edge("base_link", "camera_optical", &mount(), first).encode(),
    );
    for (t, frame) in &drive.frames {
        let t = &(t + CLOCK_NS);
        let header = |id: &str| Header::new(*t, id);
        let body = map_to_odom().inverse() * frame.left_to_world * mount().inverse();
        put(
            keys::LEFT_INFO,
            *t,
            camera_info(&rig.intrinsics, 0.0, header("camera_optical")).encode(),
        );
        put(
            keys::RIGHT_INFO,
            *t,
            camera_info(
                &rig.intrinsics,
                rig.baseline,
                header("camera_right_optical"),
            )
            .encode(),
        );
        put(keys::TF, *t, edge("odom", "base_link", &body, *t).encode());
        let odometry = Odometry {
            header: header("odom"),
            child_frame_id: "base_link".into(),
            pose: PoseWithCovariance {
                pose: pose_from_affine(&body, header("odom")).pose,
                ..PoseWithCovariance::default()
            },
            ..Odometry::default()
        };
        put(keys::ODOMETRY, *t, odometry.encode());
        for (topic, img, id) in [
            (keys::LEFT_COMPRESSED, &frame.left, "camera_optical"),
            (keys::RIGHT_COMPRESSED, &frame.right, "camera_right_optical"),
        ] {
            let rgb8 = Rgb8Image {
                width: img.width,
                height: img.height,
                data: img.to_rgb8(),
            };
            let jpeg = compressed_image(&rgb8, Compression::Jpeg { quality: 95 }, header(id));
            put(topic, *t, jpeg.unwrap().encode());
        }
    }
    bag.finish().unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_rclpy_robot_with_jpeg_images_and_tf_drives_the_node_through_the_bridge() {
    python_support::require_ros2("rclpy, sensor_msgs.msg, nav_msgs.msg, tf2_msgs.msg, mcap");
    let (drive, logs) = bridge_drive("ros2robot", 7);
    let bins = drive.bins_opened(8.0);
    let keys = Keys::new("stereosplat");
    let inputs = drive.dir("robot.mcap");
    write_robot_inputs(&drive, &keys, &inputs);
    // Apart from ros2_bridge.rs's 100-199; Fast DDS takes domain ids up to 232.
    let domain = 20 + std::process::id() % 80;
    let node = RunningNode::start(NodeConfig {
        pose_source: Some(PoseSourceConfig::new(
            PoseSourceKind::Tf,
            Some("map".into()),
        )),
        ..sgm_config(&keys)
    })
    .await;
    let poses = Collector::connect(&node, &[keys.bin_pose()]).await;
    let _bridge = start_bridge(&node, domain, &drive, &logs).await;
    let inputs_arg = inputs.display().to_string();
    let mut publisher: Running = Running::start(
        rclpy_node(domain, &["publish", "--robot", "--mcap", &inputs_arg]),
        "publisher",
        &logs,
    );
    let published = tokio::task::spawn_blocking(move || {
        // The next JSON line (a ROS 2 library may print a line of its own to stdout).
        let mut json = || {
            for _ in 0..20 {
                let line = publisher.line(&logs);
                match serde_json::from_str::<Value>(&line) {
                    Ok(v) => return v,
                    Err(_) => println!("publisher said: {}", line.trim()),
                }
            }
            panic!("the publisher printed no JSON in 20 lines")
        };
        assert_eq!(json()["matched"], true);
        json()
    })
    .await
    .unwrap();
    println!("published by rclpy: {published}");
    assert!(poses.wait_count(&keys.bin_pose(), bins).await, "every bin");
    let summary = node.stop().await;
    let c = &summary.counters;
    assert_eq!(summary.bins_published, bins as u64, "{c:?}");
    assert_eq!(c.sum("bad_message/"), 0, "{c:?}");
    assert_eq!(
        c.get("pose_source/ready"),
        drive.frames.len() as u64,
        "{c:?}"
    );
    // Each bin at the pose of a frame of the drive (the one that opened it).
    for p in poses.decoded::<PoseStamped>(&keys.bin_pose()) {
        let got = affine_from_pose(&p).unwrap().translation;
        let nearest = drive
            .poses()
            .iter()
            .map(|f| f.translation.distance(got))
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 1e-6, "a bin {nearest} m from every frame");
    }
}
