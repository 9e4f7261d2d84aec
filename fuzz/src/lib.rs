//! What the fuzz targets share: a scratch directory for the decoders that read files, and the
//! split of one fuzzer input into several files.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// This process's scratch directory (under the system temporary directory, one per process
/// so parallel fuzzing jobs do not overwrite each other's files).
pub fn scratch_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("stereosplat-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("the temporary directory is writable");
        dir
    })
}

/// Writes `bytes` to `name` in [`scratch_dir`] and returns its path, for decoders that take
/// a path.
pub fn scratch_file(name: &str, bytes: &[u8]) -> PathBuf {
    let path = scratch_dir().join(name);
    write_file(&path, bytes);
    path
}

/// Writes `bytes` to `path`, creating its parent directories (a path under [`scratch_dir`]).
pub fn write_file(path: &Path, bytes: &[u8]) {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).expect("the scratch directory is writable");
    }
    std::fs::write(path, bytes).expect("the scratch directory is writable");
}

/// `data` cut at its first `N - 1` NUL bytes into `N` parts (the last ones empty when there
/// are fewer NULs): one fuzzer input becomes several text files, and the seeds join files with
/// a NUL, which no text file of the formats holds.
pub fn split<const N: usize>(data: &[u8]) -> [&[u8]; N] {
    let mut parts = [&data[data.len()..]; N];
    let mut rest = data;
    for part in parts.iter_mut().take(N - 1) {
        match rest.iter().position(|&b| b == 0) {
            Some(at) => {
                *part = &rest[..at];
                rest = &rest[at + 1..];
            }
            None => {
                *part = rest;
                rest = &rest[rest.len()..];
            }
        }
    }
    parts[N - 1] = rest;
    parts
}
