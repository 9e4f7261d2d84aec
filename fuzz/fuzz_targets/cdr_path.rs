//! `nav_msgs/Path` payloads (a SLAM back end's corrected trajectory): CDR, then every pose's
//! stamp and rigid transform.
//! The body is `node::untrusted_input::cdr_path`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_path(data));
