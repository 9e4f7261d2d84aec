//! The payloads `stereosplat monitor` reads: `stereosplat_msgs/BinLatency` and
//! `stereosplat_msgs/Diagnostics` (each input is tried as both).
//! The body is `node::untrusted_input::cdr_latency`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_latency(data));
