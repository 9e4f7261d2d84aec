//! The node's whole input path (`Inputs::on_sample`): the input as one sample on each input
//! topic, then as a stream of length-prefixed samples. Needs the `runtime` feature.
//! The body is `node::untrusted_input::live::node_inputs`, which the test suite's seeded
//! mutations call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::live::node_inputs(data));
