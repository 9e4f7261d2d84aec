//! `stereosplat research enhancer-data`: the one-step enhancer's training pairs, renders of the
//! bins' other frames by the project's own StereoSplat against their true images (see
//! `model::enhance::make_pairs`). Bounded by `--pairs`, seeded, resumable: run it again and it
//! continues after the last whole draw.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use model::bins::BinConfig;
use model::enhance::make_pairs::{make_pairs, DataConfig, Source};
use model::net::{default_weights, Config};

use super::train::bins_of;
use crate::progress;

/// Flags of `enhancer-data`.
#[derive(Args, Clone, Debug)]
pub struct EnhancerDataArgs {
    /// KITTI-360-layout root of the drives (every sequence under it).
    #[arg(long)]
    data: PathBuf,
    /// Folder of the pairs (`pairs.csv` and five PNGs per pair).
    #[arg(long)]
    out: PathBuf,
    /// Stop once the folder holds this many pairs.
    #[arg(long, default_value_t = 2000)]
    pairs: usize,
    /// Seed of the draws (bin, input pairs, weights, targets).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Most input stereo pairs per draw (K ~ U{1..max}; the bin's first pair always).
    #[arg(long, default_value_t = 3)]
    max_pairs: usize,
    /// Frames rendered per draw.
    #[arg(long, default_value_t = 4)]
    targets: usize,
    /// StereoSplat weights to draw from, `LABEL=PATH[@KEY=VALUE,...]` (repeatable; preset
    /// `--preset` with the settings after `@`). Default: the shipped weights, as `shipped`.
    #[arg(long = "weights", value_name = "LABEL=PATH[@SETTINGS]")]
    weights: Vec<String>,
    /// StereoSplat preset of every weights file.
    #[arg(long, default_value = model::methods::DEFAULT_PRESET)]
    preset: String,
    /// Distance between a bin's first and last frames, metres (as `train --bin-length`: 8
    /// for streets, 0.5 for rooms, 0.1 for desks).
    #[arg(long, default_value_t = BinConfig::default().length_m)]
    bin_length: f64,
}

/// Parses one `--weights` value.
fn source(preset: &str, spec: &str) -> Result<Source> {
    let Some((label, rest)) = spec.split_once('=') else {
        bail!("--weights `{spec}` is not LABEL=PATH[@KEY=VALUE,...]");
    };
    if label.is_empty() || label.contains(',') {
        bail!("--weights label `{label}` must be non-empty and without commas");
    }
    let (path, settings) = match rest.split_once('@') {
        Some((path, settings)) => (path, settings.split(',').collect::<Vec<_>>()),
        None => (rest, Vec::new()),
    };
    Ok(Source {
        label: label.to_string(),
        config: Config::preset(preset)?.with_settings(&settings)?,
        path: PathBuf::from(path),
    })
}

/// Runs `enhancer-data`.
pub fn run(args: &EnhancerDataArgs) -> Result<()> {
    let sources = match args.weights.is_empty() {
        true => vec![Source {
            label: "shipped".into(),
            config: Config::preset(&args.preset)?,
            path: default_weights(&args.preset),
        }],
        false => args
            .weights
            .iter()
            .map(|s| source(&args.preset, s))
            .collect::<Result<_>>()?,
    };
    let cfg = DataConfig {
        pairs: args.pairs,
        seed: args.seed,
        max_input_pairs: args.max_pairs.max(1),
        targets: args.targets.max(1),
        bins: bins_of(args.bin_length)?,
    };
    let bar = progress::bar(args.pairs, "pairs");
    let count = make_pairs(
        &args.data,
        &args.out,
        &sources,
        &cfg,
        &mut progress::hook(&bar),
    )
    .with_context(|| format!("making pairs in {}", args.out.display()))?;
    bar.finish();
    println!("{count} pairs in {}", args.out.display());
    Ok(())
}
