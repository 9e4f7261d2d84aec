//! `tf2_msgs/TFMessage` payloads (what `/tf` and `/tf_static` listeners decode): CDR, then
//! each transform's stamp and rotation as a rigid transform.
//! The body is `node::untrusted_input::cdr_tf`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::cdr_tf(data));
