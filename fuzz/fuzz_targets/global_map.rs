//! The global map's checkpoint file (`global_map.ssgmap`) as `run` reads it when it resumes:
//! parsed from bytes, then every Gaussian walked and the map snapshot taken, as the node does
//! before it publishes the resumed map.
#![no_main]

use std::path::Path;

use node::fusion::GlobalMap;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Ok(map) = GlobalMap::from_bytes(data, Path::new("global_map.ssgmap")) else {
        return;
    };
    let finite = map.gaussians().filter(|(_, g)| g.position.is_finite()).count();
    let _ = (finite, map.len(), map.last_bin_id(), map.snapshot());
});
