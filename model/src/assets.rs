//! Where the shipped weights come from, wherever the binary is installed: a binary copied
//! into a container or installed with `cargo install` has no checkout beside it.
//!
//! The shipped network and enhancer weights and LPIPS's ([`SHIPPED`], 15 MB) are embedded
//! in the binary. [`weights_file`] looks for a file of that name, in order:
//! 1. the folder `$STEREOSPLAT_WEIGHTS` names ([`WEIGHTS_ENV`]), when set;
//! 2. `weights/` beside the executable;
//! 3. the embedded copy, which goes by the path `embedded:<name>` ([`EMBEDDED`]) and is read
//!    from memory by [`read`] and [`load_tensors`]: nothing is written anywhere.
//!
//! A name with no embedded copy and no file in 1 or 2 gives the path of 1 (or 2) that was
//! looked at, which the loaders report as missing. Retrained weights written into
//! `model/weights/` are embedded by the next build (cargo tracks the included files).

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use candle_core::{Device, Tensor};

/// The prefix of the path an embedded file goes by.
pub const EMBEDDED: &str = "embedded:";

/// The environment variable naming a folder of weight files that take precedence.
pub const WEIGHTS_ENV: &str = "STEREOSPLAT_WEIGHTS";

/// The weight files embedded in the binary: name and bytes.
pub const SHIPPED: [(&str, &[u8]); 4] = [
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
    (
        "lpips_alex.safetensors",
        include_bytes!("../weights/lpips_alex.safetensors"),
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
    if embedded(name).is_some() {
        return PathBuf::from(format!("{EMBEDDED}{name}"));
    }
    from_env
        .or(beside_exe)
        .unwrap_or_else(|| PathBuf::from(name))
}

/// The embedded bytes of the file `name`.
fn embedded(name: &str) -> Option<&'static [u8]> {
    SHIPPED.iter().find(|(n, _)| *n == name).map(|(_, b)| *b)
}

/// The embedded bytes `path` names, when it is an [`EMBEDDED`] path of a shipped file.
fn embedded_path(path: &Path) -> Option<&'static [u8]> {
    embedded(path.to_str()?.strip_prefix(EMBEDDED)?)
}

/// Whether `path` names a file, or an embedded one.
pub fn exists(path: &Path) -> bool {
    embedded_path(path).is_some() || path.is_file()
}

/// The bytes of `path`: an embedded file's from memory, any other's from disk.
pub fn read(path: &Path) -> std::io::Result<Cow<'static, [u8]>> {
    match embedded_path(path) {
        Some(bytes) => Ok(Cow::Borrowed(bytes)),
        None => std::fs::read(path).map(Cow::Owned),
    }
}

/// The tensors of the safetensors file `path` (embedded or on disk) on `device`.
pub fn load_tensors(path: &Path, device: &Device) -> candle_core::Result<HashMap<String, Tensor>> {
    match embedded_path(path) {
        Some(bytes) => candle_core::safetensors::load_buffer(bytes, device),
        None => candle_core::safetensors::load(path, device),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shipped_file_is_safetensors_of_the_checkout_and_loads_from_memory() {
        for (name, bytes) in SHIPPED {
            let file = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("weights")
                .join(name);
            assert_eq!(std::fs::read(&file).unwrap(), bytes, "{name}");
            let path = PathBuf::from(format!("{EMBEDDED}{name}"));
            assert!(exists(&path));
            assert_eq!(read(&path).unwrap(), bytes);
            let from_memory = load_tensors(&path, &Device::Cpu).unwrap();
            let from_disk = load_tensors(&file, &Device::Cpu).unwrap();
            assert_eq!(from_memory.len(), from_disk.len(), "{name}");
            assert!(!from_memory.is_empty(), "{name}");
        }
    }

    #[test]
    fn a_name_found_nowhere_is_the_path_looked_at_and_unknown_embedded_names_are_not() {
        let p = weights_file("stereosplat_nothing.safetensors");
        assert!(!exists(&p), "{}", p.display());
        assert!(p.ends_with("stereosplat_nothing.safetensors"));
        let unknown = Path::new("embedded:stereosplat_nothing.safetensors");
        assert!(!exists(unknown));
        assert!(read(unknown).is_err());
    }
}
