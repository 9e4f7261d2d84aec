//! `stereosplat research interpolate-weights`: a weight file on the straight line between two
//! trained end points of the same network, `(1 - t) * from + t * to` tensor by tensor (how the
//! shipped `tiny-3d` weights keep the streets after their fine-tuning on rooms; see
//! `model::train::interpolate`).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use model::train::interpolate_files;

/// Flags of `interpolate-weights`.
#[derive(Args, Clone, Debug)]
pub struct InterpolateWeightsArgs {
    /// The end point at `t = 0` (e.g. the weights before fine-tuning).
    #[arg(long)]
    from: PathBuf,
    /// The end point at `t = 1` (e.g. the fine-tuned weights).
    #[arg(long)]
    to: PathBuf,
    /// How far along the line, in [0, 1].
    #[arg(long)]
    t: f64,
    /// The safetensors file to write.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `interpolate-weights`: writes the file and prints `weights: <out>` on stdout.
pub fn run(args: &InterpolateWeightsArgs) -> Result<()> {
    let n = interpolate_files(&args.from, &args.to, args.t, &args.out).with_context(|| {
        format!(
            "interpolating {} and {}",
            args.from.display(),
            args.to.display()
        )
    })?;
    eprintln!("{n} tensors at t = {}", args.t);
    println!("weights: {}", args.out.display());
    Ok(())
}
