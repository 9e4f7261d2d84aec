//! `sensor_msgs/CameraInfo` payloads as the node's inputs take them: CDR, then the intrinsics
//! and baseline.
#![no_main]

use node::msg::image::intrinsics_from_camera_info;
use node::msg::sensor_msgs::CameraInfo;
use node::msg::Message;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(msg) = CameraInfo::decode(data) {
        let _ = intrinsics_from_camera_info(&msg);
    }
});
