//! Where the shipped weights come from, wherever the binary is installed: a binary copied
//! into a container or installed with `cargo install` has no checkout beside it.
//!
//! The shipped network and enhancer weights ([`SHIPPED`], 5.2 MB) are embedded in the
//! binary. [`weights_file`] looks for a file of that name, in order:
//! 1. the folder `$STEREOSPLAT_WEIGHTS` names ([`WEIGHTS_ENV`]), when set;
//! 2. `weights/` beside the executable;
//! 3. the embedded copy, written once into the user's cache folder
//!    (`$XDG_CACHE_HOME/stereosplat/weights-<version>/`, else `~/.cache/...`, else the
//!    system's temporary folder), so every loader reads a file as before.
//!
//! A name with no embedded copy and no file in 1 or 2 gives the path of 1 (or 2) that was
//! looked at, which the loaders report as missing. Retrained weights written into
//! `model/weights/` are embedded by the next build (cargo tracks the included files).

use std::path::{Path, PathBuf};

/// The environment variable naming a folder of weight files that take precedence.
pub const WEIGHTS_ENV: &str = "STEREOSPLAT_WEIGHTS";

/// The weight files embedded in the binary: name and bytes.
pub const SHIPPED: [(&str, &[u8]); 3] = [
    (
        "stereosplat_tiny.safetensors",
        include_bytes!("../weights/stereosplat_tiny.safetensors"),
    ),
    (
        "stereosplat_tiny-3d.safetensors",
        include_bytes!("../weights/stereosplat_tiny-3d.safetensors"),
    ),
    (
        "enhancer_tiny.safetensors",
        include_bytes!("../weights/enhancer_tiny.safetensors"),
    ),
];

/// The weight file `name` (a file name, no folders), found as the module documentation
/// says.
pub fn weights_file(name: &str) -> PathBuf {
    let from_env = std::env::var_os(WEIGHTS_ENV)
        .filter(|d| !d.is_empty())
        .map(|d| PathBuf::from(d).join(name));
    let beside_exe = std::env::current_exe()
        .ok()
        .and_then(|exe| exe.parent().map(|d| d.join("weights").join(name)));
    for candidate in from_env.iter().chain(&beside_exe) {
        if candidate.is_file() {
            return candidate.clone();
        }
    }
    let embedded = SHIPPED.iter().find(|(n, _)| *n == name);
    if let Some(path) = embedded.and_then(|(_, bytes)| cached(name, bytes)) {
        return path;
    }
    from_env
        .or(beside_exe)
        .unwrap_or_else(|| PathBuf::from(name))
}

/// The cache folders to try, most preferred first.
fn cache_dirs() -> Vec<PathBuf> {
    let version = format!("weights-{}", env!("CARGO_PKG_VERSION"));
    let xdg = std::env::var_os("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from);
    let home = std::env::var_os("HOME")
        .filter(|d| !d.is_empty())
        .map(|h| PathBuf::from(h).join(".cache"));
    xdg.into_iter()
        .chain(home)
        .chain([std::env::temp_dir()])
        .map(|d| d.join("stereosplat").join(&version))
        .collect()
}

/// `bytes` as the file `name` in the first cache folder that holds it or takes it; `None`
/// when none can.
fn cached(name: &str, bytes: &[u8]) -> Option<PathBuf> {
    cache_dirs().into_iter().find_map(|dir| {
        let path = dir.join(name);
        let current = std::fs::read(&path).is_ok_and(|held| held == bytes);
        (current || write_atomically(&dir, &path, bytes).is_ok()).then_some(path)
    })
}

/// Writes `bytes` to `path` through a file of its own in `dir`, renamed over `path`: a reader
/// (another process starting at the same time) sees the whole file or none.
fn write_atomically(dir: &Path, path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let tmp = dir.join(format!(
        ".{}.{}.{:?}.tmp",
        path.file_name().unwrap_or_default().to_string_lossy(),
        std::process::id(),
        std::thread::current().id()
    ));
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_embedded_file_is_cached_once_and_a_stale_copy_replaced() {
        let (name, bytes) = SHIPPED[0];
        let dir = std::env::temp_dir().join(format!("stereosplat-assets-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let path = dir.join(name);
        assert!(write_atomically(&dir, &path, b"stale").is_ok());
        // `cached` replaces what differs; done here on the folder directly.
        let held = std::fs::read(&path).unwrap();
        assert_ne!(held, bytes);
        write_atomically(&dir, &path, bytes).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), bytes);
        // No temporary file is left behind.
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(left.len(), 1);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn every_shipped_file_is_safetensors_of_the_checkout() {
        for (name, bytes) in SHIPPED {
            let file = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("weights")
                .join(name);
            assert_eq!(std::fs::read(&file).unwrap(), bytes, "{name}");
            // safetensors: an 8-byte little-endian header length, then JSON.
            let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
            assert_eq!(bytes[8], b'{', "{name}");
            assert!(8 + n <= bytes.len(), "{name}");
        }
    }

    #[test]
    fn a_name_found_nowhere_is_the_path_looked_at() {
        let p = weights_file("stereosplat_nothing.safetensors");
        assert!(!p.is_file(), "{}", p.display());
        assert!(p.ends_with("stereosplat_nothing.safetensors"));
    }
}
