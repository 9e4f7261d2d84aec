//! SPZ files (gzip) as `renderer::formats::spz::read_spz` reads them.
//! The body is `node::untrusted_input::spz`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::spz(data));
