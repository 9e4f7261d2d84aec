//! Launch files as `stereosplat launch` reads them: the TOML schema, then the checks of the
//! plan (vars, names, `after` references and their regular expressions, cycles).
#![no_main]

use std::path::Path;

use node::launch::Plan;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Plan::parse(text, Path::new("fuzz.toml"), &[], Path::new("stereosplat"));
    }
});
