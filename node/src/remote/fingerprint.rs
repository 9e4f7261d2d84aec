//! What a reconstructor is, as the node and a worker process compare it: the method, the
//! preset, the settings and the SHA-256 of the weights file. Two processes with the same
//! fingerprint make the same map of the same bin (bit for bit at the same thread count), so
//! a worker whose fingerprint differs from the node's is refused rather than let mix
//! another network's maps into the node's.

use model::methods::MethodSpec;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::msg::{CdrReader, CdrWriter, DecodeError};

/// A reconstructor's identity.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fingerprint {
    /// The method (`stereosplat`, `sgm`).
    pub method: String,
    /// The learned method's preset (empty for a classical one).
    pub preset: String,
    /// The `KEY=VALUE` settings, in the order given.
    pub settings: Vec<String>,
    /// SHA-256 of the weights file, lowercase hex (empty for a method without weights).
    pub weights_sha256: String,
}

/// Why a fingerprint could not be made.
#[derive(Debug, thiserror::Error)]
#[error("reading the weights {path} to fingerprint them")]
pub struct FingerprintError {
    /// The weights file.
    pub path: PathBuf,
    /// What failed.
    #[source]
    pub source: std::io::Error,
}

impl Fingerprint {
    /// The fingerprint of what `spec` builds ([`MethodSpec::build`]): a learned method's
    /// preset defaults to `tiny` and its weights to the preset's shipped file, as there.
    pub fn of(spec: &MethodSpec) -> Result<Self, FingerprintError> {
        let weights_sha256 = match spec.weights_file() {
            Some(path) => sha256_file(&path)?,
            None => String::new(),
        };
        Ok(Self {
            method: spec.method.clone(),
            preset: spec.preset_name().unwrap_or_default().to_string(),
            settings: spec.settings.clone(),
            weights_sha256,
        })
    }

    /// One line for errors and logs: `stereosplat tiny [k=v] weights 3f2a…`.
    pub fn describe(&self) -> String {
        let mut s = self.method.clone();
        if !self.preset.is_empty() {
            s += &format!(" preset {}", self.preset);
        }
        if !self.settings.is_empty() {
            s += &format!(" settings [{}]", self.settings.join(", "));
        }
        if !self.weights_sha256.is_empty() {
            s += &format!(" weights sha256 {}", &self.weights_sha256);
        }
        s
    }

    /// Appends the fields.
    pub fn write(&self, w: &mut CdrWriter) {
        w.string(&self.method);
        w.string(&self.preset);
        w.seq_len(self.settings.len());
        for s in &self.settings {
            w.string(s);
        }
        w.string(&self.weights_sha256);
    }

    /// Reads the fields.
    pub fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let method = r.string("method")?;
        let preset = r.string("preset")?;
        // A string is at least its 4-byte length and a NUL.
        let n = r.seq_len("settings", 5)?;
        let settings = (0..n)
            .map(|_| r.string("setting"))
            .collect::<Result<_, _>>()?;
        Ok(Self {
            method,
            preset,
            settings,
            weights_sha256: r.string("weights_sha256")?,
        })
    }
}

fn sha256_file(path: &Path) -> Result<String, FingerprintError> {
    let err = |source| FingerprintError {
        path: path.to_path_buf(),
        source,
    };
    // Weight files are a few MB: read whole (an embedded one from memory).
    let bytes = model::assets::read(path).map_err(err)?;
    let mut hasher = Sha256::new();
    hasher.update(&bytes);
    Ok(hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}
