//! `stereosplat_msgs/MapUpdate` payloads as a map subscriber takes them: CDR, then the
//! increment or snapshot they carry.
//! The body is `node::untrusted_input::cdr_map_update`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_map_update(data));
