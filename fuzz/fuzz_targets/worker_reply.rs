//! Replies of a worker process (the worker protocol, CDR), as the node decodes them, then
//! fused and converted as the node does. Needs the `runtime` feature.
//! The body is `node::untrusted_input::live::worker_reply`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::live::worker_reply(data));
