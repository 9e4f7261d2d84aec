//! `stereosplat synth` and `stereosplat synth-heldout`: synthetic drives in the KITTI-360
//! layout, for training (any seed below the held-out range) and for evaluation (seeds from
//! [`HELDOUT_SEED_BASE`] up, which training never uses).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use model::generate::{write_synthetic, HELDOUT_SEED_BASE};
use model::kitti360::Sequence;
use model::synth::{Randomisation, SynthConfig};

use super::progress;

/// Flags shared by both commands: the size and look of the drive.
#[derive(Args, Clone, Debug)]
pub struct DriveArgs {
    /// Data root to write into (created if missing; other sequences in it are kept).
    #[arg(long)]
    out: PathBuf,
    /// Frames per sequence (10 per second of driving).
    #[arg(long, default_value_t = SynthConfig::default().frames)]
    frames: u32,
    /// Image width in pixels (KITTI-360's 1408 x 376 intrinsics are scaled to it).
    #[arg(long, default_value_t = SynthConfig::default().width)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = SynthConfig::default().height)]
    height: u32,
    /// Samples per pixel along each axis (anti-aliasing).
    #[arg(long, default_value_t = SynthConfig::default().supersample)]
    supersample: u32,
    /// Domain randomisation (docs/evaluation.md, "Synthetic drives"): photo textures, lighting, a rig and
    /// image size of its own (so `--width`/`--height` are unused), camera effects and
    /// floating objects, all drawn from the seed.
    #[arg(long)]
    randomise: bool,
}

impl DriveArgs {
    fn config(&self, seed: u64) -> SynthConfig {
        SynthConfig {
            seed,
            frames: self.frames,
            width: self.width,
            height: self.height,
            supersample: self.supersample,
            randomise: self.randomise.then(Randomisation::default),
            ..SynthConfig::default()
        }
    }
}

/// Flags of `synth`.
#[derive(Args, Clone, Debug)]
pub struct SynthArgs {
    #[command(flatten)]
    drive: DriveArgs,
    /// Seed of the street and the drive (below the held-out range).
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// Flags of `synth-heldout`.
#[derive(Args, Clone, Debug)]
pub struct HeldoutArgs {
    #[command(flatten)]
    drive: DriveArgs,
    /// How many held-out sequences (seeds HELDOUT_SEED_BASE, +1, ...).
    #[arg(long, default_value_t = 1)]
    sequences: u64,
}

/// Writes one training drive.
pub fn run(args: &SynthArgs) -> Result<()> {
    if args.seed >= HELDOUT_SEED_BASE {
        bail!("seeds from {HELDOUT_SEED_BASE} up are held out; use `synth-heldout` for them");
    }
    write(&args.drive, args.seed)
}

/// Writes the held-out drives.
pub fn run_heldout(args: &HeldoutArgs) -> Result<()> {
    for k in 0..args.sequences {
        write(&args.drive, HELDOUT_SEED_BASE + k)?;
    }
    Ok(())
}

fn write(drive: &DriveArgs, seed: u64) -> Result<()> {
    let config = drive.config(seed);
    let bar = progress::bar(config.frames as usize, "synth");
    let name = write_synthetic(&drive.out, &config, &mut progress::hook(&bar))?;
    bar.finish_and_clear();
    let (width, height) = config.size();
    println!(
        "wrote {} frames of {name} ({width}x{height}) under {}",
        config.frames,
        drive.out.display()
    );
    Ok(())
}

/// The generated drive of `config` under `root`, written (with a progress bar) unless a
/// sequence of that seed, length and size is already there; returns its name.
pub fn cached_drive(root: &Path, config: &SynthConfig) -> Result<String> {
    let name = model::generate::sequence_name(config.seed);
    let ready = Sequence::open(root, &name).is_ok_and(|s| {
        let k = s.rig().intrinsics;
        s.frames().len() == config.frames as usize && (k.width, k.height) == config.size()
    });
    if !ready {
        let bar = progress::bar(config.frames as usize, "generate");
        write_synthetic(root, config, &mut progress::hook(&bar))?;
        bar.finish_and_clear();
    }
    Ok(name)
}

/// The first sequence under a KITTI-360-layout root.
pub fn first_sequence(root: &Path) -> Result<String> {
    Sequence::list(root)?
        .into_iter()
        .next()
        .with_context(|| format!("no sequence under {}", root.display()))
}
