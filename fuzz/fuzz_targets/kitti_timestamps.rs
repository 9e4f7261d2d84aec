//! KITTI-360 `timestamps.txt` files as `read_timestamps` reads them.
#![no_main]

use model::kitti360::timestamps::read_timestamps;
use stereosplat_fuzz::scratch_file;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = read_timestamps(&scratch_file("timestamps.txt", data));
});
