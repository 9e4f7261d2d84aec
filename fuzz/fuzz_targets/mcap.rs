//! MCAP files as `replay --mcap` reads them: the summary, then every message in log-time
//! order (the input is written to a scratch file, since the reader takes a path).
#![no_main]

use node::bag::BagReader;
use stereosplat_fuzz::scratch_file;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = scratch_file("bag.mcap", data);
    let Ok(bag) = BagReader::open(&path) else {
        return;
    };
    let _ = (bag.channels().len(), bag.message_count(), bag.time_range());
    for message in bag.messages() {
        if message.is_err() {
            break;
        }
    }
});
