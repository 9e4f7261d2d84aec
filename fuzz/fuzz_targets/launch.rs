//! Launch files as `stereosplat launch` reads them: the TOML schema, then the checks of the
//! plan (vars, names, `after` references and their regular expressions, cycles).
//! The body is `node::untrusted_input::launch`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::launch(data));
