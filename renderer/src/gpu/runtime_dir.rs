//! A private `XDG_RUNTIME_DIR` for the process when the environment has none. Mesa's
//! lavapipe (the Vulkan driver wgpu runs on without a GPU) prints `error: XDG_RUNTIME_DIR is
//! invalid or not set` when it is missing, every time a device is opened, which a newcomer
//! reads as a failure; nothing of ours uses the folder. `Context::new` ensures it
//! once per process before the first instance, and the `stereosplat` binary at its start.

use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};

/// The variable Mesa checks.
const VAR: &str = "XDG_RUNTIME_DIR";

/// Points `XDG_RUNTIME_DIR` at `<temp>/stereosplat-runtime-<uid>` (created with mode 0700)
/// when it is unset or does not name a folder of this user with mode 0700, as Mesa wants.
/// It changes the environment: call it before threads start where possible (`main`); the
/// GPU context calls it once per process before its first instance.
/// Returns the folder it set, `None` when the variable was fine or no folder could be made
/// (then Mesa only prints its message).
pub fn ensure_runtime_dir() -> Option<PathBuf> {
    let uid = std::fs::metadata("/proc/self").ok()?.uid();
    if std::env::var_os(VAR).is_some_and(|d| is_private_dir(Path::new(&d), uid)) {
        return None;
    }
    let dir = std::env::temp_dir().join(format!("stereosplat-runtime-{uid}"));
    if std::fs::create_dir(&dir).is_err() && !dir.is_dir() {
        return None;
    }
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).ok()?;
    if !is_private_dir(&dir, uid) {
        return None;
    }
    std::env::set_var(VAR, &dir);
    Some(dir)
}

/// True when `dir` is a folder owned by `uid` that only its owner may enter.
fn is_private_dir(dir: &Path, uid: u32) -> bool {
    std::fs::symlink_metadata(dir)
        .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.mode() & 0o077 == 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn private_dir_check_wants_owner_only_folders() {
        let uid = std::fs::metadata("/proc/self").unwrap().uid();
        let base = std::env::temp_dir().join(format!("ss-rt-test-{}", std::process::id()));
        std::fs::create_dir_all(&base).unwrap();
        std::fs::set_permissions(&base, std::fs::Permissions::from_mode(0o755)).unwrap();
        assert!(!is_private_dir(&base, uid), "0755 is not private");
        std::fs::set_permissions(&base, std::fs::Permissions::from_mode(0o700)).unwrap();
        assert!(is_private_dir(&base, uid));
        assert!(!is_private_dir(&base, uid + 1), "another user's folder");
        assert!(!is_private_dir(&base.join("missing"), uid));
        std::fs::remove_dir_all(&base).unwrap();
    }
}
