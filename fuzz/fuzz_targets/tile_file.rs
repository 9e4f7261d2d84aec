//! A tile file of the fused map (`<x>_<y>_<version>.sstile`), read as the map pages it in.
//! The body is `node::untrusted_input::tile_file`, which the test suite's seeded mutations call
//! too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::tile_file(data));
