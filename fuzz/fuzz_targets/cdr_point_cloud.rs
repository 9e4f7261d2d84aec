//! `sensor_msgs/PointCloud2` payloads as a listener takes a bin's map: CDR, then the Gaussians
//! (bin frame, and relative to a far origin as a world-frame cloud is read).
#![no_main]

use glam::DVec3;
use node::msg::gaussians::gaussians_from_cloud;
use node::msg::sensor_msgs::PointCloud2;
use node::msg::Message;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(cloud) = PointCloud2::decode(data) {
        let _ = gaussians_from_cloud(&cloud, DVec3::ZERO);
        let _ = gaussians_from_cloud(&cloud, DVec3::new(1e5, -2.5e5, 30.0));
    }
});
