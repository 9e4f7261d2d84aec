//! `stereosplat research eval-enhancer`: PSNR (whole image and unseen region) and LPIPS of the raw
//! render and of the enhanced render against the true image, on held-out pairs from
//! `enhancer-data`; JSON on stdout and in `--out`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use model::enhance::evaluate::evaluate;
use model::enhance::pairs::PairSet;
use model::enhance::{default_weights, load, Config};
use model::lpips::Lpips;

use crate::progress;

/// Flags of `eval-enhancer`.
#[derive(Args, Clone, Debug)]
pub struct EvalEnhancerArgs {
    /// Folder of held-out pairs (from `enhancer-data` on drives training never saw).
    #[arg(long)]
    pairs: PathBuf,
    /// Enhancer preset.
    #[arg(long, default_value = model::methods::ENHANCER_PRESET)]
    preset: String,
    /// Enhancer weights (default: the shipped `model/weights/enhancer_<preset>.safetensors`).
    #[arg(long)]
    weights: Option<PathBuf>,
    /// Pairs per forward pass.
    #[arg(long, default_value_t = 8)]
    batch: usize,
    /// JSON file to write (also printed).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `eval-enhancer`.
pub fn run(args: &EvalEnhancerArgs) -> Result<()> {
    let cfg = Config::preset(&args.preset)?;
    let weights = args
        .weights
        .clone()
        .unwrap_or_else(|| default_weights(&args.preset));
    let enhancer = load(&cfg, &weights, &candle_core::Device::Cpu)
        .with_context(|| format!("loading {}", weights.display()))?;
    let set = PairSet::open(&args.pairs)?;
    let lpips = Lpips::load_default()?;
    let bar = progress::bar(set.len(), "pairs");
    let report = evaluate(
        &enhancer,
        &set,
        &lpips,
        args.batch,
        &mut progress::hook(&bar),
    )?;
    bar.finish();
    let json = serde_json::to_string_pretty(&report)?;
    if let Some(out) = &args.out {
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)?;
        }
        std::fs::write(out, &json).with_context(|| format!("writing {}", out.display()))?;
    }
    println!("{json}");
    Ok(())
}
