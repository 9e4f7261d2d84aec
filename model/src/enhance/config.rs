//! The enhancer's sizes, one struct with named presets (`tiny`, `small`), as the network's
//! own `Config`.

use serde::{Deserialize, Serialize};

/// Sizes of the one-step enhancer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Config {
    /// The preset's name, recorded in weight files (`enhancer_<name>.safetensors`).
    pub name: String,
    /// Channels of the stem at 1/2 resolution.
    pub stem_channels: usize,
    /// Channels of the three U-Net levels at 1/4, 1/8 and 1/16 resolution.
    pub channels: [usize; 3],
    /// Residual blocks per level (encoder and decoder alike).
    pub blocks: usize,
    /// Joint-attention layers at 1/16 resolution (render and reference tokens together).
    pub attention_layers: usize,
    /// Attention heads (divides `channels[2]`).
    pub heads: usize,
}

/// The preset names [`Config::preset`] knows.
pub const PRESETS: &[&str] = &["tiny", "small"];

/// A preset name [`Config::preset`] does not know.
#[derive(Debug, thiserror::Error)]
#[error("unknown enhancer preset `{0}` (known: {known})", known = PRESETS.join(", "))]
pub struct UnknownPreset(pub String);

impl Config {
    /// The 2-core CPU's size: 32/48/64 channels, one block per level, one attention layer.
    pub fn tiny() -> Self {
        Self {
            name: "tiny".into(),
            stem_channels: 16,
            channels: [32, 48, 64],
            blocks: 1,
            attention_layers: 1,
            heads: 4,
        }
    }

    /// Twice the layers and about twice the width, for a GPU or a longer budget.
    pub fn small() -> Self {
        Self {
            name: "small".into(),
            stem_channels: 24,
            channels: [48, 64, 96],
            blocks: 2,
            attention_layers: 2,
            heads: 4,
        }
    }

    /// The preset called `name`.
    pub fn preset(name: &str) -> Result<Self, UnknownPreset> {
        match name {
            "tiny" => Ok(Self::tiny()),
            "small" => Ok(Self::small()),
            other => Err(UnknownPreset(other.to_string())),
        }
    }
}
