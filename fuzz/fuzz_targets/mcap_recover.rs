//! MCAP files read as cut-off recordings (`BagReader::recover`): complete chunks from the
//! start, then every message of the recovered part.
//! The body is `node::untrusted_input::mcap_recover`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::mcap_recover(data));
