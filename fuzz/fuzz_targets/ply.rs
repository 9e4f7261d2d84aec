//! 3DGS PLY files (ASCII and binary) as `renderer::ply::read_ply` reads them.
//! The body is `node::untrusted_input::ply`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::ply(data));
