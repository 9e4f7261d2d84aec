//! `sensor_msgs/CameraInfo` payloads as the node's inputs take them: CDR, then the intrinsics
//! and baseline.
//! The body is `node::untrusted_input::cdr_camera_info`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_camera_info(data));
