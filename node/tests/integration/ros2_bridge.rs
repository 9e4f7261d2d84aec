//! A real ROS 2 node talks to the StereoSplat node: two rclpy nodes (ROS 2 Jazzy from the
//! wheels, Fast DDS) on one side, the node (plain keys, namespace `stereosplat`) on the
//! other, and between them the zenoh project's ROS 2 bridge (`zenoh-plugin-ros2dds` 1.10.2
//! with Cyclone DDS, `ros2_bridge/`, a workspace member). The publisher node
//! publishes a generated drive as sensor_msgs/Image, CameraInfo and PoseStamped (read from an
//! MCAP file this test writes, deserialized by rclpy); the listener node subscribes to the
//! bin maps, bin poses, latency and diagnostics. Every bin the node publishes arrives in the
//! listener with its fields, and the same width as a zenoh subscriber sees.
//!
//! Everything stays on 127.0.0.1: zenoh peers listen and connect on loopback with scouting
//! off; Cyclone DDS binds the loopback interface with multicast off and 127.0.0.1 as its only
//! peer (`launch/cyclonedds_localhost.xml` plus the plugin's `LOCALHOST` discovery range);
//! Fast DDS runs `launch/fastdds_localhost.xml` (UDPv4 on 127.0.0.1 only, unicast discovery).
//! While they run, the test checks that no process joined the RTPS multicast group
//! 239.255.0.1 (`/proc/net/igmp`) and that every UDP socket of the three processes is bound
//! to 127.0.0.1 (Cyclone's receive sockets: to any address, which Cyclone hard-codes; it
//! sends only to 127.0.0.1). A domain id of its own keeps it apart from other DDS tests.
//!
//! Needs the bridge built (`cargo test --workspace` builds it; alone, `bash
//! scripts/ros2_bridge.sh`) and the Python side of `.ci/setup`; without them it fails and says
//! what to run.

use crate::drive_support;
use crate::python_support;

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};

use drive_support::{bin_of_frame_id, Collector, Drive, RunningNode};
use model::synth::SynthConfig;
use node::bag::BagWriter;
use node::clients::channel_of;
use node::msg::image::{camera_info, image_from_rgb};
use node::msg::pose::pose_from_affine;
use node::msg::sensor_msgs::PointCloud2;
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::pipeline::worker::RenderWith;
use node::service::NodeConfig;
use node::transport::keys::{self, Topic};
use node::transport::Keys;
use serde_json::Value;

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

/// The field names of a bin map, in order: the 3DGS fields, then the packed colour.
const FIELDS: [&str; 16] = [
    "x",
    "y",
    "z",
    "f_dc_0",
    "f_dc_1",
    "f_dc_2",
    "opacity",
    "scale_0",
    "scale_1",
    "scale_2",
    "rot_0",
    "rot_1",
    "rot_2",
    "rot_3",
    "confidence",
    "rgb",
];

/// A child process killed (and reaped) when dropped, so a failing test leaves none behind.
pub(crate) struct Running {
    child: Child,
    /// Its stdout when piped (`None` when the command sent it elsewhere).
    stdout: Option<BufReader<ChildStdout>>,
    what: &'static str,
}

impl Running {
    /// Starts `command` with stderr to a file under `logs` and stdout piped unless the
    /// command already sends it elsewhere.
    pub(crate) fn start(mut command: Command, what: &'static str, logs: &Path) -> Self {
        let stderr = std::fs::File::create(logs.join(format!("{what}.stderr"))).unwrap();
        let mut child = command
            .stderr(stderr)
            .stdin(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("starting the {what}: {e}"));
        let stdout = child.stdout.take().map(BufReader::new);
        Self {
            child,
            stdout,
            what,
        }
    }

    /// The next line it prints (blocking); panics with its stderr when it ends instead.
    pub(crate) fn line(&mut self, logs: &Path) -> String {
        let mut line = String::new();
        let stdout = self.stdout.as_mut().expect("a piped stdout");
        stdout.read_line(&mut line).expect("reading stdout");
        if line.trim().is_empty() {
            let _ = self.child.wait();
            let err = std::fs::read_to_string(logs.join(format!("{}.stderr", self.what)));
            panic!(
                "the {} printed nothing:\n{}",
                self.what,
                err.unwrap_or_default()
            );
        }
        line
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Whether any process on this machine joined the RTPS default multicast group 239.255.0.1
/// (`/proc/net/igmp` lists groups as little-endian hex: `0100FFEF`).
fn rtps_multicast_joined() -> bool {
    let mut text = String::new();
    std::fs::File::open("/proc/net/igmp")
        .and_then(|mut f| f.read_to_string(&mut text))
        .expect("/proc/net/igmp");
    text.contains("0100FFEF")
}

/// The local addresses (`a.b.c.d:port`) of the UDP sockets process `pid` holds, read from
/// its open files and `/proc/net/udp`.
fn udp_sockets_of(pid: u32) -> Vec<String> {
    let inodes: Vec<String> = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .map(|dir| {
            dir.filter_map(|e| std::fs::read_link(e.ok()?.path()).ok())
                .filter_map(|l| {
                    let l = l.to_string_lossy().into_owned();
                    Some(l.strip_prefix("socket:[")?.strip_suffix(']')?.to_owned())
                })
                .collect()
        })
        .unwrap_or_default();
    let table = std::fs::read_to_string("/proc/net/udp").unwrap_or_default();
    table
        .lines()
        .skip(1)
        .filter_map(|line| {
            let cols: Vec<&str> = line.split_whitespace().collect();
            let inode = *cols.get(9)?;
            if !inodes.iter().any(|i| i == inode) {
                return None;
            }
            let (ip, port) = cols.get(1)?.split_once(':')?;
            let ip = u32::from_str_radix(ip, 16).ok()?.to_le_bytes();
            let port = u16::from_str_radix(port, 16).ok()?;
            Some(format!("{}.{}.{}.{}:{port}", ip[0], ip[1], ip[2], ip[3]))
        })
        .collect()
}

/// The drive's inputs as `stereosplat record` writes them: camera infos, images and pose of
/// every frame on the node's input channels.
fn write_inputs(drive: &Drive, keys: &Keys, path: &Path) {
    let mut bag = BagWriter::create(path).unwrap();
    let mut put = |topic: Topic, t: i64, payload: Vec<u8>| {
        let time = t as u64;
        bag.write(&channel_of(keys, topic), time, time, 1, &payload)
            .unwrap();
    };
    let rig = &drive.rig;
    for (t, frame) in &drive.frames {
        let header = |id: &str| Header::new(*t, id);
        put(
            keys::LEFT_INFO,
            *t,
            camera_info(&rig.intrinsics, 0.0, header("left")).encode(),
        );
        put(
            keys::RIGHT_INFO,
            *t,
            camera_info(&rig.intrinsics, rig.baseline, header("right")).encode(),
        );
        put(
            keys::LEFT_IMAGE,
            *t,
            image_from_rgb(&frame.left, header("left")).encode(),
        );
        put(
            keys::RIGHT_IMAGE,
            *t,
            image_from_rgb(&frame.right, header("right")).encode(),
        );
        put(
            keys::POSE,
            *t,
            pose_from_affine(&frame.left_to_world, header("world")).encode(),
        );
    }
    bag.finish().unwrap();
}

/// `scripts/ros2_drive_node.py ARGS` through `scripts/ros2_env.sh`, on ROS domain `domain`,
/// with the loopback-only Fast DDS profile. (Not `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`:
/// with it, Jazzy's rmw_fastrtps binds 0.0.0.0 and opens a socket on the machine's other
/// interface, seen here; the profile alone keeps every socket on 127.0.0.1.)
pub(crate) fn rclpy_node(domain: u32, args: &[&str]) -> Command {
    let mut c = Command::new("bash");
    c.arg(python_support::ROS2_ENV)
        .stdout(Stdio::piped())
        .arg("python3")
        .arg(format!("{ROOT}/scripts/ros2_drive_node.py"))
        .args(args)
        .env("ROS_DOMAIN_ID", domain.to_string())
        .env(
            "FASTRTPS_DEFAULT_PROFILES_FILE",
            format!("{ROOT}/launch/fastdds_localhost.xml"),
        );
    c
}

/// A generated 30-frame drive at 136x40 of `seed` under a folder named after `tag`, with a
/// `logs` folder for the processes' output.
pub(crate) fn bridge_drive(tag: &str, seed: u64) -> (Drive, PathBuf) {
    let drive = Drive::generate(
        tag,
        &SynthConfig {
            seed,
            frames: 30,
            width: 136,
            height: 40,
            ..SynthConfig::default()
        },
    );
    let logs = drive.dir("logs");
    std::fs::create_dir_all(&logs).unwrap();
    (drive, logs)
}

/// The zenoh ROS 2 bridge between `node` and ROS domain `domain` (loopback only), started
/// and ready.
pub(crate) async fn start_bridge(
    node: &RunningNode,
    domain: u32,
    drive: &Drive,
    logs: &Path,
) -> Running {
    let bridge = PathBuf::from(format!("{ROOT}/target/release/stereosplat-ros2-bridge"));
    assert!(
        bridge.exists(),
        "{} is missing: run `cargo test --workspace` or `bash scripts/ros2_bridge.sh`",
        bridge.display()
    );
    let config = drive.dir("bridge.json5");
    let template = std::fs::read_to_string(format!("{ROOT}/launch/ros2_bridge.json5")).unwrap();
    let text = template
        .replace("tcp/127.0.0.1:7447", &node.endpoint)
        .replace("domain: 0,", &format!("domain: {domain},"));
    std::fs::write(&config, text).unwrap();
    let cyclone =
        std::fs::read_to_string(format!("{ROOT}/launch/cyclonedds_localhost.xml")).unwrap();
    let mut command = Command::new(&bridge);
    command
        .arg(&config)
        .env("CYCLONEDDS_URI", cyclone.trim())
        .env("ROS_DISTRO", "jazzy");
    // The bridge logs to stdout too: into a file (never a full pipe), read until ready.
    let out = logs.join("bridge.stdout");
    command.stdout(std::fs::File::create(&out).unwrap());
    let bridge = Running::start(command, "bridge", logs);
    let ready = drive_support::wait_for(std::time::Duration::from_secs(60), || {
        std::fs::read_to_string(&out).is_ok_and(|t| t.lines().any(|l| l == "bridge ready"))
    })
    .await;
    assert!(
        ready,
        "the bridge did not start: {}",
        std::fs::read_to_string(&out).unwrap()
    );
    bridge
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_rclpy_node_gets_every_bin_through_the_zenoh_ros2_bridge() {
    python_support::require_ros2("rclpy, sensor_msgs.msg, stereosplat_msgs.msg, mcap");
    let (drive, logs) = bridge_drive("ros2bridge", 6);
    let bins = drive.bins_opened(8.0);
    let keys = Keys::new("stereosplat");
    let inputs = drive.dir("inputs.mcap");
    write_inputs(&drive, &keys, &inputs);
    let domain = 100 + std::process::id() % 100;

    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        method: "sgm".into(),
        renders: RenderWith::Off,
        queue_capacity: 64,
        ..NodeConfig::default()
    })
    .await;
    let zenoh_maps = Collector::connect(&node, &[keys.bin_map()]).await;

    let bridge = start_bridge(&node, domain, &drive, &logs).await;

    let bins_arg = bins.to_string();
    let mut listener = Running::start(
        rclpy_node(domain, &["listen", "--bins", &bins_arg, "--timeout", "240"]),
        "listener",
        &logs,
    );
    let listener_ready: Value = serde_json::from_str(&listener.line(&logs)).unwrap();
    assert_eq!(listener_ready["ready"], true);
    let inputs_arg = inputs.display().to_string();
    let mut publisher = Running::start(
        rclpy_node(domain, &["publish", "--mcap", &inputs_arg]),
        "publisher",
        &logs,
    );
    let pids = [
        ("bridge", bridge.child.id()),
        ("listener", listener.child.id()),
        ("publisher", publisher.child.id()),
    ];
    let (published, got, multicast, sockets) = tokio::task::spawn_blocking(move || {
        // Sockets and multicast groups while all three run: the publisher has matched the
        // bridge's readers and is about to drive (a fixed sleep was too short on a loaded
        // machine, where importing rclpy alone can take seconds).
        let matched: Value = serde_json::from_str(&publisher.line(&logs)).unwrap();
        assert_eq!(matched["matched"], true);
        let sockets: Vec<_> = pids
            .iter()
            .map(|&(what, pid)| (what, udp_sockets_of(pid)))
            .collect();
        let multicast = rtps_multicast_joined();
        let published: Value = serde_json::from_str(&publisher.line(&logs)).unwrap();
        let got: Value = serde_json::from_str(&listener.line(&logs)).unwrap();
        (published, got, multicast, sockets)
    })
    .await
    .unwrap();
    println!("UDP sockets: {sockets:?}");
    drop(bridge);
    let summary = node.stop().await;
    println!("published by rclpy: {published}");
    println!(
        "node: {} bins; counters {:?}",
        summary.bins_published, summary.counters
    );

    assert!(
        !multicast,
        "a process joined the RTPS multicast group 239.255.0.1"
    );
    // Fast DDS (the XML profile) binds only 127.0.0.1. Cyclone DDS binds its receive
    // sockets to INADDR_ANY whatever the interface (hard-coded in its ddsi_udp.c), sends from
    // 127.0.0.1 and only to its peer 127.0.0.1: never another interface's address.
    for (what, bound) in &sockets {
        assert!(
            !bound.is_empty(),
            "{what} holds no UDP socket: is it a DDS participant?"
        );
        for addr in bound {
            let any_ok = *what == "bridge" && addr.starts_with("0.0.0.0:");
            assert!(
                addr.starts_with("127.0.0.1:") || any_ok,
                "{what} bound UDP {addr}"
            );
        }
    }
    assert_eq!(published["published"]["pose"], drive.frames.len());
    assert_eq!(
        summary.bins_published, bins as u64,
        "every frame reached the node"
    );

    // Every bin in the rclpy listener: map with the 3DGS fields and the width a zenoh
    // subscriber saw, pose in the world at the map's stamp.
    let maps = got["maps"].as_array().expect("maps");
    let poses = got["poses"].as_array().expect("poses");
    assert_eq!((maps.len(), poses.len()), (bins, bins), "{got}");
    let zenoh: Vec<PointCloud2> = zenoh_maps.decoded(&keys.bin_map());
    for (i, (map, pose)) in maps.iter().zip(poses).enumerate() {
        let frame = map["frame_id"].as_str().unwrap();
        let ours = zenoh
            .iter()
            .find(|c| c.header.frame_id == frame)
            .unwrap_or_else(|| panic!("{frame} on zenoh"));
        assert_eq!(
            bin_of_frame_id(frame),
            bin_of_frame_id(&zenoh[i].header.frame_id)
        );
        assert_eq!(map["fields"], serde_json::json!(FIELDS), "{frame}");
        assert_eq!(map["width"], ours.width, "{frame}");
        assert_eq!(map["height"], 1);
        assert_eq!(map["point_step"], 64, "15 f32 fields and the packed rgb");
        assert_eq!(map["bytes"], ours.data.len(), "{frame}");
        assert!(ours.width > 0, "{frame} is empty");
        assert_eq!(pose["frame_id"], "world");
        assert_eq!(pose["stamp_ns"], map["stamp_ns"], "{frame}");
    }
    // Latency for every closed bin (all but the last), diagnostics at least once a second.
    let mut closed: Vec<u64> = maps
        .iter()
        .map(|m| bin_of_frame_id(m["frame_id"].as_str().unwrap()))
        .collect();
    closed.sort_unstable();
    closed.pop();
    let latency: Vec<u64> = got["latency_bins"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| b.as_u64().unwrap())
        .collect();
    assert_eq!(latency, closed);
    assert!(got["diagnostics"].as_u64().unwrap() >= 1, "{got}");
}
