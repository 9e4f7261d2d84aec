//! `tf2_msgs/TFMessage` payloads (what `/tf` and `/tf_static` listeners decode): CDR, then
//! each transform's stamp and rotation as a rigid transform.
#![no_main]

use glam::{DQuat, DVec3};
use node::msg::tf2_msgs::TfMessage;
use node::msg::Message;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(msg) = TfMessage::decode(data) {
        for t in &msg.transforms {
            let _ = t.header.stamp.to_nanos();
            let (p, q) = (t.transform.translation, t.transform.rotation);
            let _ = glam::DAffine3::from_rotation_translation(
                DQuat::from_xyzw(q.x, q.y, q.z, q.w),
                DVec3::new(p.x, p.y, p.z),
            );
        }
    }
});
