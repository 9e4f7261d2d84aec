//! Reconstructors by name, so every command (`eval`, the node) picks one the same way and a
//! new method is added in one place.
//!
//! - `sgm`: the classical baseline (semi-global matching), its defaults changed by
//!   `KEY=VALUE` settings of [`SgmConfig`] (e.g. `median=false`, `paths=five`).
//! - `stereosplat`: the learned network, preset `tiny` unless another is given, with the
//!   preset's shipped weights (`model/weights/stereosplat_<preset>.safetensors`) unless a
//!   weight file is given; with `--set progressive=true`, StereoSplat+'s progressive pass
//!   around it (`model::progressive`) with the `tiny` enhancer
//!   (`model/weights/enhancer_tiny.safetensors`) unless `enhancer=false`.
//!
//! A [`MethodSpec`] names one as a value (method, preset, weights, settings): what the
//! command line's flags, the node's config, an operating point and a worker's fingerprint
//! all carry.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::baseline::{SgmConfig, SgmReconstructor};
use crate::enhance;
use crate::net::{
    apply_settings, default_weights, Config, LearnedReconstructor, LoadError, SettingError,
    UnknownPreset,
};
use crate::progressive::ProgressiveReconstructor;
use crate::reconstruct::Reconstructor;
use renderer::RenderWith;

/// The names [`by_name`] knows.
pub const NAMES: &[&str] = &["sgm", "stereosplat"];

/// The reconstructor every command (the node, `demo`, `eval`, `bench node`) uses when none is
/// named: the learned network with the shipped `tiny` weights, which beats `sgm` on held-out
/// PSNR and AbsRel (`bash scripts/eval_tiny.sh`, `results/stereosplat_tiny/`); `sgm` stays
/// the faster choice.
pub const DEFAULT: &str = "stereosplat";

/// The preset of `stereosplat` when none is given.
pub const DEFAULT_PRESET: &str = "tiny";

/// The enhancer preset the progressive pass loads (the one the 2-core CPU runs per bin).
pub const ENHANCER_PRESET: &str = "tiny";

/// Why a reconstructor could not be made.
#[derive(Debug, thiserror::Error)]
pub enum MethodError {
    /// A name [`by_name`] does not know.
    #[error("unknown method `{0}` (known: {known})", known = NAMES.join(", "))]
    Unknown(String),
    /// A preset name that does not exist.
    #[error(transparent)]
    Preset(#[from] UnknownPreset),
    /// A preset setting that does not apply.
    #[error(transparent)]
    Setting(#[from] SettingError),
    /// The learned model's weights could not be loaded.
    #[error(transparent)]
    Weights(#[from] LoadError),
    /// The progressive pass's enhancer could not be loaded.
    #[error("enhancer weights {path}: {source} (train them with scripts/train_enhancer.sh, or run the pass without: `--set enhancer=false`)")]
    Enhancer {
        /// The file.
        path: std::path::PathBuf,
        /// Why (boxed: the enhancer's error is large).
        #[source]
        source: Box<crate::enhance::EnhanceError>,
    },
}

/// A reconstructor as one value: the method ([`NAMES`]), a learned method's preset (`None`:
/// [`DEFAULT_PRESET`]) and weights (`None`: the preset's shipped file), and `KEY=VALUE`
/// settings ([`build`] says what each means).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct MethodSpec {
    /// The method ([`NAMES`]).
    pub method: String,
    /// A learned method's preset.
    pub preset: Option<String>,
    /// A learned method's weight file.
    pub weights: Option<PathBuf>,
    /// `KEY=VALUE` settings, in the order given.
    pub settings: Vec<String>,
}

impl Default for MethodSpec {
    /// [`DEFAULT`] with its preset's shipped weights and no settings.
    fn default() -> Self {
        Self::from(DEFAULT)
    }
}

impl From<&str> for MethodSpec {
    /// The method `name` with its defaults.
    fn from(name: &str) -> Self {
        Self {
            method: name.to_string(),
            preset: None,
            weights: None,
            settings: Vec::new(),
        }
    }
}

impl MethodSpec {
    /// The reconstructor this names ([`build`]).
    pub fn build(&self) -> Result<Box<dyn Reconstructor + Send>, MethodError> {
        build(
            &self.method,
            self.preset.as_deref(),
            self.weights.as_deref(),
            &self.settings,
        )
    }

    /// Whether it is the learned method (which has a preset and weights).
    pub fn learned(&self) -> bool {
        self.method == "stereosplat"
    }

    /// The preset a learned method runs ([`DEFAULT_PRESET`] when none is named); `None` for
    /// a classical one.
    pub fn preset_name(&self) -> Option<&str> {
        self.learned()
            .then(|| self.preset.as_deref().unwrap_or(DEFAULT_PRESET))
    }

    /// The weight file a learned method loads (its own, or the preset's shipped file);
    /// `None` for a classical one.
    pub fn weights_file(&self) -> Option<PathBuf> {
        let preset = self.preset_name()?;
        Some(
            self.weights
                .clone()
                .unwrap_or_else(|| default_weights(preset)),
        )
    }
}

/// The reconstructor called `name`, with its default settings.
pub fn by_name(name: &str) -> Result<Box<dyn Reconstructor + Send>, MethodError> {
    build(name, None, None, &[])
}

/// The reconstructor called `name`; for `stereosplat`, of `preset` (default `tiny`) changed by
/// `KEY=VALUE` `settings` ([`Config::with_settings`]), with the weights at `weights` (default:
/// the preset's shipped file); for `sgm`, its default [`SgmConfig`] changed by `settings`.
pub fn build(
    name: &str,
    preset: Option<&str>,
    weights: Option<&Path>,
    settings: &[String],
) -> Result<Box<dyn Reconstructor + Send>, MethodError> {
    match name {
        "sgm" => Ok(Box::new(SgmReconstructor::new(apply_settings(
            SgmConfig::default(),
            settings,
        )?))),
        "stereosplat" => {
            let cfg = Config::preset(preset.unwrap_or(DEFAULT_PRESET))?.with_settings(settings)?;
            let path = weights.map_or_else(|| default_weights(&cfg.name), Path::to_path_buf);
            let learned = LearnedReconstructor::load(&cfg, &path)?;
            if !cfg.progressive {
                return Ok(Box::new(learned));
            }
            let enhancer = match cfg.enhancer {
                true => {
                    let path = cfg
                        .enhancer_weights
                        .clone()
                        .unwrap_or_else(|| enhance::default_weights(ENHANCER_PRESET));
                    let preset = enhance::Config::tiny();
                    let device = learned.device();
                    Some(enhance::load(&preset, &path, &device).map_err(|e| {
                        MethodError::Enhancer {
                            path,
                            source: Box::new(e),
                        }
                    })?)
                }
                false => None,
            };
            Ok(Box::new(ProgressiveReconstructor::new(
                learned,
                enhancer,
                RenderWith::Auto,
            )))
        }
        other => Err(MethodError::Unknown(other.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spec_names_its_preset_and_weights_only_for_the_learned_method() {
        let default = MethodSpec::default();
        assert_eq!(default.method, DEFAULT);
        assert_eq!(default.preset_name(), Some(DEFAULT_PRESET));
        assert_eq!(
            default.weights_file(),
            Some(default_weights(DEFAULT_PRESET))
        );
        let own = MethodSpec {
            preset: Some("tiny-3d".into()),
            weights: Some("w.safetensors".into()),
            ..MethodSpec::default()
        };
        assert_eq!(own.preset_name(), Some("tiny-3d"));
        assert_eq!(own.weights_file(), Some(PathBuf::from("w.safetensors")));
        let sgm = MethodSpec::from("sgm");
        assert_eq!((sgm.preset_name(), sgm.weights_file()), (None, None));
        assert!(sgm.build().is_ok());
        assert!(matches!(
            MethodSpec::from("nope").build(),
            Err(MethodError::Unknown(_))
        ));
    }
}
