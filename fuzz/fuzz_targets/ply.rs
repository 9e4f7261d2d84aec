//! 3DGS PLY files (ASCII and binary) as `renderer::ply::read_ply` reads them.
#![no_main]

use renderer::ply::read_ply;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = read_ply(data);
});
