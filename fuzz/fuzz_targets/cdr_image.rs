//! `sensor_msgs/Image` payloads as the node's inputs take them: CDR, then the RGB conversion
//! of the encoding named and of every other encoding read.
//! The body is `node::untrusted_input::cdr_image`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_image(data));
