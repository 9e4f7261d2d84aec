//! The query string of the live view's `/api/tiles` and `/map/tile.ply` requests, as its
//! server checks it. Needs the `runtime` feature.
//! The body is `node::untrusted_input::live::view_http_params`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::live::view_http_params(data));
