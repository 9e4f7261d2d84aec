//! The global map's checkpoint file (`global_map.ssgmap`) as `run` reads it when it resumes:
//! parsed from bytes, then every Gaussian walked and the map snapshot taken, as the node does
//! before it publishes the resumed map.
//! The body is `node::untrusted_input::global_map`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::global_map(data));
