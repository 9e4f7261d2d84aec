//! `nav_msgs/Odometry` payloads as an odometry pose source takes them: CDR, the body's pose
//! as a rigid transform, the camera's pose through a mount, and the pose as a tf edge.
//! The body is `node::untrusted_input::cdr_odometry`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_odometry(data));
