//! Requests to a worker process (the worker protocol, CDR), as `stereosplat worker` reads
//! them: the kind from the first bytes, then the whole request. Needs the `runtime` feature
//! (`--features runtime`).
//! The body is `node::untrusted_input::live::worker_request`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::live::worker_request(data));
