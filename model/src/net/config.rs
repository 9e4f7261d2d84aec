//! The one preset struct: every setting of the network that trades speed for accuracy, with
//! named presets (`tiny`, `small`, `paper`) that every command selects by name.

use serde::{Deserialize, Serialize};

/// Sizes and ranges of the StereoSplat cost-volume network.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Config {
    /// The preset's name (`tiny`, `small`, `paper`), recorded in weight files and reports.
    pub name: String,
    /// Channels of the shared image backbone at 1/4 resolution.
    pub backbone_channels: usize,
    /// Residual blocks of the backbone at 1/4 resolution.
    pub backbone_blocks: usize,
    /// Channels of the monocular geometry encoder (the role of Depth-Anything-V2 features).
    pub mono_channels: usize,
    /// Residual blocks of the geometry encoder at 1/8 resolution.
    pub mono_blocks: usize,
    /// Multi-view transformer layers (each: windowed self-attention, cross-attention to the
    /// other views in the same window, MLP).
    pub transformer_layers: usize,
    /// Attention heads.
    pub heads: usize,
    /// Attention window (rows, columns) at 1/4 resolution.
    pub window: (usize, usize),
    /// Channels the per-view features are projected to before correlation.
    pub cost_channels: usize,
    /// Depth candidates of the plane sweep (the paper's disparity candidates).
    pub candidates: usize,
    /// Nearest depth candidate, metres.
    pub near: f32,
    /// Farthest depth candidate, metres (sky lands here).
    pub far: f32,
    /// How many nearest views (by camera translation) each reference view matches against.
    pub match_views: usize,
    /// Channels of the U-Net depth head.
    pub unet_channels: usize,
    /// Channels of the Gaussian heads.
    pub head_channels: usize,
    /// One Gaussian per `gaussian_stride` x `gaussian_stride` pixels of each view.
    pub gaussian_stride: usize,
    /// Gaussians below this opacity are not emitted.
    pub opacity_floor: f32,
    /// At most this many Gaussians per reconstruction (the most opaque are kept).
    pub max_gaussians: usize,
}

/// The preset names [`Config::preset`] knows.
pub const PRESETS: &[&str] = &["tiny", "small", "paper"];

/// A preset name [`Config::preset`] does not know.
#[derive(Debug, thiserror::Error)]
#[error("unknown preset `{0}` (known: {known})", known = PRESETS.join(", "))]
pub struct UnknownPreset(pub String);

impl Config {
    /// Real time on a 2-core CPU: small channels, 32 candidates, Gaussians at 1/2 resolution.
    pub fn tiny() -> Self {
        Self {
            name: "tiny".into(),
            backbone_channels: 32,
            backbone_blocks: 1,
            mono_channels: 16,
            mono_blocks: 1,
            transformer_layers: 1,
            heads: 2,
            window: (4, 16),
            cost_channels: 32,
            candidates: 32,
            near: 1.0,
            far: 100.0,
            match_views: 2,
            unet_channels: 32,
            head_channels: 24,
            gaussian_stride: 2,
            opacity_floor: 0.02,
            max_gaussians: 200_000,
        }
    }

    /// Twice the channels and candidates of `tiny`, two transformer layers.
    pub fn small() -> Self {
        Self {
            name: "small".into(),
            backbone_channels: 64,
            backbone_blocks: 2,
            mono_channels: 32,
            mono_blocks: 2,
            transformer_layers: 2,
            heads: 4,
            window: (4, 16),
            cost_channels: 64,
            candidates: 64,
            unet_channels: 48,
            head_channels: 48,
            ..Self::tiny()
        }
    }

    /// The paper's settings: 192 candidates, Gaussians at full resolution, six transformer
    /// layers (DepthSplat's), 128-channel features.
    pub fn paper() -> Self {
        Self {
            name: "paper".into(),
            backbone_channels: 128,
            backbone_blocks: 3,
            mono_channels: 64,
            mono_blocks: 4,
            transformer_layers: 6,
            heads: 4,
            window: (8, 16),
            cost_channels: 128,
            candidates: 192,
            match_views: 2,
            unet_channels: 64,
            head_channels: 64,
            gaussian_stride: 1,
            max_gaussians: 2_000_000,
            ..Self::tiny()
        }
    }

    /// The preset called `name`.
    pub fn preset(name: &str) -> Result<Self, UnknownPreset> {
        match name {
            "tiny" => Ok(Self::tiny()),
            "small" => Ok(Self::small()),
            "paper" => Ok(Self::paper()),
            other => Err(UnknownPreset(other.to_string())),
        }
    }

    /// Features of one view that enter the cost volume: geometry plus transformer output.
    pub fn view_channels(&self) -> usize {
        self.backbone_channels + self.mono_channels
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_named_preset_resolves_to_itself() {
        for name in PRESETS {
            assert_eq!(Config::preset(name).unwrap().name, *name);
        }
        assert!(Config::preset("huge").is_err());
        assert_eq!(Config::paper().candidates, 192);
    }
}
