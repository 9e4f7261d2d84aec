//! A generated drive written once per test process: the tests of one binary run in parallel
//! threads, and two writers in one folder collide on its calibration file.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Mutex;

use model::generate::write_synthetic;
use model::synth::SynthConfig;

/// The drive `config` describes, under a folder named after `tag` and the process, written
/// by the first caller (the others wait for it): its root and sequence name.
pub fn once(tag: &str, config: &SynthConfig) -> (PathBuf, String) {
    static DRIVES: Mutex<BTreeMap<String, (PathBuf, String)>> = Mutex::new(BTreeMap::new());
    let mut drives = DRIVES.lock().unwrap_or_else(|e| e.into_inner());
    drives
        .entry(tag.to_string())
        .or_insert_with(|| {
            let root =
                std::env::temp_dir().join(format!("stereosplat-{tag}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&root);
            let name = write_synthetic(&root, config, &mut |_, _| {}).expect("drive written");
            (root, name)
        })
        .clone()
}
