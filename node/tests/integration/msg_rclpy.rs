//! Byte-exact interop with the real ROS 2 Jazzy typesupport: `scripts/ros2_typesupport.py`
//! runs rclpy's `serialize_message` / `deserialize_message` (the C typesupport of the
//! `ros-jazzy-*` wheels, Fast CDR underneath). For every message type the node reads or
//! writes (Image, CameraInfo, PoseStamped, PointCloud2 in a bin and the world frame,
//! TFMessage, and the node's own BinLatency, Diagnostics, MapUpdate), rclpy reads the node's
//! bytes to the same field values, and rclpy's bytes for those values are the node's bytes
//! exactly (except alignment padding, which Fast CDR leaves uninitialised: the node writes
//! zeros there) and decode in Rust to the same message. tf2_msgs and stereosplat_msgs have no
//! wheel: `scripts/ros2_msgs.sh` generates their typesupport with rosidl's own CMake
//! generators from the wheels (stereosplat_msgs from `node/src/msg/*.msg`).
//!
//! Type hashes: every type's RIHS01 hash equals the one in the type description its ROS 2
//! package installs (`share/<pkg>/msg/<Type>.json`, written by
//! rosidl_generator_type_description: the wheels' for the standard types, the generated
//! packages' for tf2_msgs and stereosplat_msgs).
//!
//! Needs the wheels of `scripts/requirements.txt` and `scripts/ros2_msgs.sh` run once (CI does
//! both in `.ci/setup`); without them the test fails and says how to get them.

use crate::msg_support;
use crate::python_support;

use msg_support::samples;
use msg_support::values::{cases, decode_requests, decodes_to_case, padded_cases, unhex};
use node::msg::{type_hash, MessageKind};
use serde_json::{json, Value};

const SCRIPT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scripts/ros2_typesupport.py"
);

/// Modules the script imports (the generated packages' included).
const MODULES: &str =
    "rclpy, sensor_msgs.msg, geometry_msgs.msg, tf2_msgs.msg, stereosplat_msgs.msg";

/// Sends one request to the script (through `scripts/ros2_env.sh`) and returns its reply.
fn rclpy(request: &Value) -> Value {
    python_support::require_ros2(MODULES);
    python_support::run_json(
        &["bash", python_support::ROS2_ENV, "python3", SCRIPT],
        request,
    )
}

#[test]
fn rclpy_reads_our_bytes_and_writes_the_same_bytes() {
    let s = samples();
    let cases = cases(&s);
    let decode = decode_requests(&cases);
    let encode: Vec<_> = cases
        .iter()
        .map(|(t, _, v)| json!({"type": t, "value": v}))
        .collect();
    let reply = rclpy(&json!({"decode": decode, "encode": encode}));

    // Ours -> rclpy: every field as meant.
    let decoded = reply["decoded"].as_array().expect("decoded list");
    assert_eq!(decoded.len(), cases.len());
    for ((t, _, want), got) in cases.iter().zip(decoded) {
        assert_eq!(got, want, "{t} as rclpy deserializes it");
    }
    // rclpy -> ours: the same bytes but for padding, decoding to the same message.
    let encoded = reply["encoded"].as_array().expect("encoded list");
    assert_eq!(encoded.len(), cases.len());
    let padded = padded_cases(&s, 0xAA);
    let (mut bytes, mut padding) = (0, 0);
    for (i, ((t, ours, _), theirs)) in cases.iter().zip(encoded).enumerate() {
        let theirs = unhex(theirs.as_str().expect("hex string"));
        assert_eq!(theirs.len(), ours.len(), "{t}: length");
        for (at, (&a, &b)) in ours.iter().zip(&theirs).enumerate() {
            let is_padding = padded[i][at] != a;
            padding += is_padding as usize;
            assert!(
                a == b || is_padding,
                "{t}: byte {at} is {b:#04x} in rclpy's, {a:#04x} in ours"
            );
        }
        bytes += ours.len();
        decodes_to_case(i, &theirs, &s, &format!("{t} from rclpy (case {i})"));
    }
    println!(
        "{} messages, {bytes} bytes equal to rclpy's but for {padding} padding bytes",
        cases.len()
    );
}

#[test]
fn type_hashes_equal_the_installed_type_descriptions() {
    let names: Vec<_> = MessageKind::ALL.iter().map(|k| k.ros_name()).collect();
    let reply = rclpy(&json!({ "installed_hashes": names }));
    for kind in MessageKind::ALL {
        assert_eq!(
            reply["installed_hashes"][kind.ros_name()],
            json!(type_hash(kind)),
            "{}",
            kind.ros_name()
        );
    }
    println!("{} type hashes equal ROS 2's", MessageKind::ALL.len());
}
