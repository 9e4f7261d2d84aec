//! `sensor_msgs/Image` payloads as the node's inputs take them: CDR, then the RGB conversion.
#![no_main]

use node::msg::image::rgb_from_image;
use node::msg::sensor_msgs::Image;
use node::msg::Message;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(msg) = Image::decode(data) {
        let _ = msg.header.stamp.to_nanos();
        let _ = rgb_from_image(&msg);
    }
});
