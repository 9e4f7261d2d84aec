//! A journal segment of the fused map, replayed onto an empty map as a restarting node
//! replays it, with the tile files its records page in (length-prefixed parts: the segment,
//! then each tile file with its version).
//! The body is `node::untrusted_input::journal_segment`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::journal_segment(data));
