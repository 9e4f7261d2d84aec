//! MCAP files as `replay --mcap` reads them: the summary, then every message in log-time
//! order (the input is written to a scratch file, since the reader takes a path).
//! The body is `node::untrusted_input::mcap`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::mcap(data));
