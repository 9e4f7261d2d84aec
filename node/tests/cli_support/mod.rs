//! Running the `stereosplat` binary as a user does, for the command-line tests.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs `stereosplat args paths`, asserts success, returns stdout.
pub fn stereosplat(args: &[&str], paths: &[&Path]) -> String {
    let run = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
        .args(args)
        .args(paths)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    String::from_utf8(run.stdout).unwrap()
}

/// A fresh, empty path under the temp dir, unique to this process.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereosplat-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}
