//! Messages on the node's topics as the live view takes them into its state (map updates,
//! bin poses, renders, latency, diagnostics, input images, camera info): the input as one
//! message on each watched topic, then as a stream of length-prefixed messages. Needs the
//! `runtime` feature.
//! The body is `node::untrusted_input::live::view_topics`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::live::view_topics(data));
