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

use std::path::Path;

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
