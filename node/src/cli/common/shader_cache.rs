//! Where Mesa keeps its compiled-shader cache. By default Mesa (lavapipe and llvmpipe, the
//! drivers wgpu runs on without a GPU) writes it under the user's home folder
//! (`~/.cache/mesa_shader_cache`), outside anything the user pointed the command at. A
//! command with an out folder keeps the cache inside it (`<out>/shader_cache`), so a second
//! run on the same folder starts as fast and nothing is left elsewhere; any other command
//! turns the cache off. A user's own `MESA_SHADER_CACHE_DIR` or `MESA_SHADER_CACHE_DISABLE`
//! wins.

use std::path::{Path, PathBuf};

/// Mesa's variable naming the cache folder.
const DIR_VAR: &str = "MESA_SHADER_CACHE_DIR";
/// Mesa's variable turning the cache off.
const DISABLE_VAR: &str = "MESA_SHADER_CACHE_DISABLE";

/// Points Mesa's shader cache into `<out>/shader_cache`, or turns it off when `out` is
/// `None` or the folder cannot be made. Call it in `main` before any thread starts (it
/// changes the environment). Returns the folder it set, if any.
pub fn place_shader_cache(out: Option<&Path>) -> Option<PathBuf> {
    if std::env::var_os(DIR_VAR).is_some() || std::env::var_os(DISABLE_VAR).is_some() {
        return None;
    }
    let dir = out
        .map(|o| o.join("shader_cache"))
        .filter(|d| std::fs::create_dir_all(d).is_ok());
    match &dir {
        Some(d) => std::env::set_var(DIR_VAR, d),
        None => std::env::set_var(DISABLE_VAR, "true"),
    }
    dir
}
