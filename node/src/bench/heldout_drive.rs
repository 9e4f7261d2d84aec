//! The generated held-out street drive at KITTI-360's frame size that `bench keep-up` and
//! `bench workers` replay at its recorded rate: its flags, and the drive itself, generated
//! once and kept.

use std::path::Path;

use anyhow::Result;
use clap::Args;
use model::generate::HELDOUT_SEED_BASE;
use model::kitti360::Sequence;
use model::synth::SynthConfig;

use crate::cli::common::drives::cached_sequence;

/// Length, frame size and seed of the drive.
#[derive(Args, Clone, Debug)]
pub struct HeldoutDriveArgs {
    /// Frames of the generated drive (10 per second of driving).
    #[arg(long, default_value_t = 300)]
    pub frames: u32,
    /// Image width of the generated drive.
    #[arg(long, default_value_t = 1408)]
    pub width: u32,
    /// Image height of the generated drive.
    #[arg(long, default_value_t = 376)]
    pub height: u32,
    /// Seed of the generated drive (held-out seeds start at 1,000,000).
    #[arg(long, default_value_t = HELDOUT_SEED_BASE + 700)]
    pub seed: u64,
}

impl HeldoutDriveArgs {
    /// The drive under `dir`, generated unless it is there already.
    pub fn sequence(&self, dir: &Path) -> Result<Sequence> {
        let synth = SynthConfig {
            seed: self.seed,
            frames: self.frames,
            width: self.width,
            height: self.height,
            ..SynthConfig::default()
        };
        cached_sequence(dir, &synth)
    }

    /// The drive's description in a report.
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "frames": self.frames,
            "size": [self.width, self.height],
            "seed": self.seed,
            "rate": 1.0,
        })
    }
}
