//! KITTI-360 `timestamps.txt` files as `read_timestamps` reads them.
//! The body is `node::untrusted_input::kitti_timestamps`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::kitti_timestamps(data));
