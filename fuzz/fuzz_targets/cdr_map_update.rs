//! `stereosplat_msgs/MapUpdate` payloads as a map subscriber takes them: CDR, then the
//! increment or snapshot they carry.
#![no_main]

use node::fusion::decode_update;
use node::msg::map_update::MapUpdate;
use node::msg::Message;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(msg) = MapUpdate::decode(data) {
        let _ = decode_update(&msg);
    }
});
