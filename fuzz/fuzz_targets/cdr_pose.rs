//! `geometry_msgs/PoseStamped` payloads as the node's inputs take them: CDR, then the rigid
//! camera-to-world transform.
#![no_main]

use node::msg::geometry_msgs::PoseStamped;
use node::msg::pose::affine_from_pose;
use node::msg::Message;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(msg) = PoseStamped::decode(data) {
        let _ = msg.header.stamp.to_nanos();
        let _ = affine_from_pose(&msg);
    }
});
