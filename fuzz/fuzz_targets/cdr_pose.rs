//! `geometry_msgs/PoseStamped` payloads as the node's inputs take them: CDR, then the rigid
//! camera-to-world transform.
//! The body is `node::untrusted_input::cdr_pose`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_pose(data));
