//! `sensor_msgs/CompressedImage` payloads as the node's inputs take them: CDR, the JPEG or
//! PNG header's size, then the pixels decoded under the default limits. The body is
//! `node::untrusted_input::cdr_compressed_image`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_compressed_image(data));
