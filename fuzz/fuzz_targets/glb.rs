//! Binary glTF files with `KHR_gaussian_splatting` as `renderer::formats::glb::read_glb`
//! reads them. The body is `node::untrusted_input::glb`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::glb(data));
