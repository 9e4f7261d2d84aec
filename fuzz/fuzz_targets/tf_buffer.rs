//! `/tf` and `/tf_static` streams through the tf buffer: length-prefixed parts, each a flag
//! byte and a `tf2_msgs/TFMessage`, every transform inserted, then every pair of frames
//! looked up at several stamps.
//! The body is `node::untrusted_input::tf_buffer`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::tf_buffer(data));
