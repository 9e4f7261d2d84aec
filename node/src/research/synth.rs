//! `stereosplat research synth` and `stereosplat research synth-heldout`: synthetic sequences
//! (streets, desks, rooms) in the KITTI-360 layout, for training (seeds below
//! [`HELDOUT_SEED_BASE`]), for validation (seeds from [`VALIDATION_SEED_BASE`] up, where
//! settings and checkpoints are chosen) and for evaluation (the held-out seeds in between,
//! which nothing else uses).

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use model::generate::{write_synthetic, HELDOUT_SEED_BASE, VALIDATION_SEED_BASE};
use model::synth::{Randomisation, RigChoice, SceneKind, SynthConfig};

use crate::progress;

/// Flags shared by both commands: the size and look of the drive.
#[derive(Args, Clone, Debug)]
pub struct DriveArgs {
    /// Data root to write into (created if missing; other sequences in it are kept).
    #[arg(long)]
    out: PathBuf,
    /// Frames per sequence (10 per second of driving).
    #[arg(long, default_value_t = SynthConfig::default().frames)]
    frames: u32,
    /// Image width in pixels (KITTI-360's 1408 x 376 intrinsics are scaled to it) [default:
    /// 272]. With `--randomise`, `--width` and `--height` fix the size the drive would
    /// otherwise draw; its field of view and baseline are still drawn.
    #[arg(long, requires = "height")]
    width: Option<u32>,
    /// Image height in pixels [default: 72].
    #[arg(long, requires = "width")]
    height: Option<u32>,
    /// Samples per pixel along each axis (anti-aliasing).
    #[arg(long, default_value_t = SynthConfig::default().supersample)]
    supersample: u32,
    /// Domain randomisation (docs/evaluation.md, "Synthetic drives"): photo textures, lighting,
    /// a rig and image size of its own (unless `--width`/`--height` fix it), camera effects and
    /// floating objects, all drawn from the seed.
    #[arg(long)]
    randomise: bool,
    /// What the sequence shows: `street` (a car rig, 1-100 m), `desk` (a handheld rig over
    /// a table, 0.2-1 m) or `room` (walking through a room, 1-10 m).
    #[arg(long, default_value = "street", value_parser = parse_scene)]
    scene: SceneKind,
    /// Stereo baseline in metres (unrandomised sequences; default: the scene's own, KITTI-360's
    /// 0.59 m for streets, 0.10 m for desks, 0.12 m for rooms).
    #[arg(long)]
    baseline: Option<f64>,
    /// Horizontal field of view in degrees, with `--baseline` (default: the scene's own; 70
    /// for desks, 75 for rooms, KITTI-360's for streets).
    #[arg(long, requires = "baseline")]
    hfov: Option<f64>,
    /// Desks and rooms: distance from the camera to what it looks at (the table top along
    /// the optical axis; the wall it faces), metres (default: drawn, 0.3-0.6 for desks,
    /// 2.5-8.5 for rooms).
    #[arg(long)]
    distance: Option<f64>,
}

/// KITTI-360's horizontal field of view, degrees: a street's with `--baseline` but no
/// `--hfov`.
fn kitti360_hfov_deg() -> f64 {
    use model::kitti360::calibration::{KITTI360_FOCAL, KITTI360_SIZE};
    2.0 * (0.5 * KITTI360_SIZE.0 as f64 / KITTI360_FOCAL)
        .atan()
        .to_degrees()
}

/// A `--scene` value.
fn parse_scene(name: &str) -> Result<SceneKind, String> {
    SceneKind::from_name(name)
        .ok_or_else(|| format!("unknown scene `{name}`: street, desk or room"))
}

impl DriveArgs {
    fn config(&self, seed: u64) -> SynthConfig {
        let default = SynthConfig::default();
        let size = self.width.zip(self.height);
        let (width, height) = size.unwrap_or((default.width, default.height));
        SynthConfig {
            seed,
            frames: self.frames,
            width,
            height,
            supersample: self.supersample,
            randomise: self.randomise.then(|| Randomisation {
                fixed_size: size,
                ..Randomisation::for_scene(self.scene)
            }),
            scene: self.scene,
            rig: self.baseline.map(|baseline_m| RigChoice {
                hfov_deg: self
                    .hfov
                    .or(self.scene.rig().map(|r| r.hfov_deg))
                    .unwrap_or_else(kitti360_hfov_deg),
                baseline_m,
            }),
            view_distance_m: self.distance,
            ..SynthConfig::default()
        }
    }
}

/// Flags of `synth`.
#[derive(Args, Clone, Debug)]
pub struct SynthArgs {
    #[command(flatten)]
    drive: DriveArgs,
    /// Seed of the scene and the camera's path: training seeds lie below 1000000, validation
    /// seeds from 2000000 up (the held-out ones between are `synth-heldout`'s).
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
    if (HELDOUT_SEED_BASE..VALIDATION_SEED_BASE).contains(&args.seed) {
        bail!(
            "seeds {HELDOUT_SEED_BASE}-{} are held out; use `synth-heldout` for them",
            VALIDATION_SEED_BASE - 1
        );
    }
    write(&args.drive, args.seed)
}

/// Writes the held-out drives.
pub fn run_heldout(args: &HeldoutArgs) -> Result<()> {
    if args.sequences > VALIDATION_SEED_BASE - HELDOUT_SEED_BASE {
        bail!(
            "at most {} held-out sequences",
            VALIDATION_SEED_BASE - HELDOUT_SEED_BASE
        );
    }
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
