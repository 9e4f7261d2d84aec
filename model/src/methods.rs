//! Reconstructors by name, so every command (`eval`, the node) picks one the same way and a
//! new method is added in one place.

use crate::baseline::{SgmConfig, SgmReconstructor};
use crate::reconstruct::Reconstructor;

/// The names [`by_name`] knows.
pub const NAMES: &[&str] = &["sgm"];

/// A name [`by_name`] does not know.
#[derive(Debug, thiserror::Error)]
#[error("unknown method `{0}` (known: {known})", known = NAMES.join(", "))]
pub struct UnknownMethod(pub String);

/// The reconstructor called `name`, with its default settings.
pub fn by_name(name: &str) -> Result<Box<dyn Reconstructor + Send>, UnknownMethod> {
    match name {
        "sgm" => Ok(Box::new(SgmReconstructor::new(SgmConfig::default()))),
        other => Err(UnknownMethod(other.to_string())),
    }
}
