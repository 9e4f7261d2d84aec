//! The payloads `stereosplat monitor` reads: `stereosplat_msgs/BinLatency` and
//! `stereosplat_msgs/Diagnostics` (each input is tried as both).
#![no_main]

use node::msg::latency::{BinLatency, Diagnostics};
use node::msg::Message;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = BinLatency::decode(data);
    let _ = Diagnostics::decode(data);
});
