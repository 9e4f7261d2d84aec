//! `stereosplat research train-enhancer`: trains the one-step enhancer on pairs from
//! `enhancer-data`, with checkpoints, resume, a CSV log, the loss curve and the weights as
//! `enhancer_<preset>.safetensors`. Ctrl-C stops after the current step with a checkpoint.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use model::enhance::loss::LossWeights;
use model::enhance::train::{exported_weights, TrainConfig, Trainer};
use model::enhance::Config;
use model::train::AdamWConfig;

use super::train::train_under_bar;

/// Flags of `train-enhancer`.
#[derive(Args, Clone, Debug)]
pub struct TrainEnhancerArgs {
    /// Folder of training pairs (from `enhancer-data`).
    #[arg(long)]
    pairs: PathBuf,
    /// Enhancer preset (tiny, small).
    #[arg(long, default_value = model::methods::ENHANCER_PRESET)]
    preset: String,
    /// Run directory: checkpoint/, log.csv, loss_curve.png, the exported weights.
    #[arg(long)]
    out: PathBuf,
    /// Continue from the run directory's checkpoint.
    #[arg(long)]
    resume: bool,
    /// Start from these enhancer weights instead of a seeded initialisation (fine-tuning on
    /// new pairs, e.g. the shipped file on renders of another StereoSplat).
    #[arg(long, conflicts_with = "resume")]
    init: Option<PathBuf>,
    /// Optimizer steps in all.
    #[arg(long, default_value_t = 3000)]
    steps: u64,
    /// Pairs per step.
    #[arg(long, default_value_t = 4)]
    batch: usize,
    /// Learning rate after warm-up.
    #[arg(long, default_value_t = 1e-3)]
    lr: f64,
    /// Linear warm-up steps.
    #[arg(long, default_value_t = 100)]
    warmup: u64,
    /// Largest global gradient norm.
    #[arg(long, default_value_t = 1.0)]
    clip: f64,
    /// Seed of the weights and batches.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Steps between checkpoints.
    #[arg(long, default_value_t = 100)]
    checkpoint_every: u64,
    /// Weight of the L2 term.
    #[arg(long, default_value_t = LossWeights::default().l2)]
    l2_weight: f64,
    /// Weight of the LPIPS term.
    #[arg(long, default_value_t = LossWeights::default().lpips)]
    lpips_weight: f64,
    /// Weight of the Gram (style) term.
    #[arg(long, default_value_t = LossWeights::default().style)]
    style_weight: f64,
}

/// Runs `train-enhancer`.
pub fn run(args: &TrainEnhancerArgs) -> Result<()> {
    let net = Config::preset(&args.preset)?;
    let cfg = TrainConfig {
        steps: args.steps,
        batch: args.batch.max(1),
        lr: args.lr,
        warmup: args.warmup,
        clip: args.clip,
        seed: args.seed,
        checkpoint_every: args.checkpoint_every.max(1),
        loss: LossWeights {
            l2: args.l2_weight,
            lpips: args.lpips_weight,
            style: args.style_weight,
        },
        adamw: AdamWConfig::default(),
    };
    let mut trainer = Trainer::new(&net, cfg, &args.pairs, &args.out, args.resume)
        .with_context(|| format!("starting training in {}", args.out.display()))?;
    if let Some(init) = &args.init {
        let loaded = trainer
            .load_weights(init)
            .with_context(|| format!("loading {}", init.display()))?;
        eprintln!("{}: {loaded} tensors loaded", init.display());
    }
    eprintln!(
        "training enhancer {} ({} weights) on {} pairs from step {} to {}",
        args.preset,
        trainer.parameters(),
        trainer.pairs(),
        trainer.step(),
        args.steps
    );
    let weights = exported_weights(&args.out, &args.preset);
    let steps = (trainer.step(), args.steps);
    train_under_bar(steps, &weights, |stop, show| {
        trainer.run(stop, &mut |r| {
            show(
                r.step,
                format!(
                    "loss {:.4} l2 {:.5} (raw {:.5}) lpips {:.3} style {:.5} {:.2} it/s",
                    r.loss, r.l2, r.raw_l2, r.lpips, r.style, r.steps_per_s
                ),
            )
        })?;
        Ok(trainer.step())
    })
}
