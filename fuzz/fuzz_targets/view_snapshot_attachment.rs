//! The JSON attached to a whole-map snapshot reply (tile side, tiles on the node's disk), as
//! the live view reads it. Needs the `runtime` feature.
//! The body is `node::untrusted_input::live::view_snapshot_attachment`, which the test suite's
//! seeded mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(
    |data: &[u8]| node::untrusted_input::live::view_snapshot_attachment(data)
);
