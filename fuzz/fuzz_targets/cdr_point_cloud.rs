//! `sensor_msgs/PointCloud2` payloads as a listener takes a bin's map: CDR, then the Gaussians
//! (bin frame, and relative to a far origin as a world-frame cloud is read).
//! The body is `node::untrusted_input::cdr_point_cloud`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_point_cloud(data));
