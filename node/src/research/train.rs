//! `stereosplat research train`: trains a preset on KITTI-360-layout roots (generated streets,
//! desks and rooms, or the real data set), with checkpoints, resume, a CSV log and the weights
//! as safetensors. Ctrl-C stops at the end of the current step after writing a checkpoint.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use clap::Args;
use model::bins::BinConfig;
use model::net::Config;
use model::train::{
    exported_weights, AdamWConfig, DataRoot, DepthError, LossWeights, SampleConfig, TrainConfig,
    Trainer,
};

use crate::progress;

/// Flags of `train`.
#[derive(Args, Clone, Debug)]
pub struct TrainArgs {
    /// KITTI-360-layout root to train on (every sequence under it). Repeatable: a mix of
    /// roots (e.g. desks, rooms, streets), each drawn equally often whatever its size.
    #[arg(long, required = true)]
    data: Vec<PathBuf>,
    /// Network preset (tiny, small, paper).
    #[arg(long, default_value = model::methods::DEFAULT_PRESET)]
    preset: String,
    /// Change a preset setting, `KEY=VALUE` (repeatable), e.g. `--set candidates=48`;
    /// give the same settings again when resuming and when evaluating the weights.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    settings: Vec<String>,
    /// Run directory: checkpoint/, log.csv, the exported weights.
    #[arg(long)]
    out: PathBuf,
    /// Continue from the run directory's checkpoint.
    #[arg(long)]
    resume: bool,
    /// Start from these weights instead of a seeded initialisation (fine-tuning, e.g. the
    /// shipped synthetic weights on real KITTI-360). Every tensor of the file the network
    /// has is loaded; the others stay seeded and are listed (a warm start: the shipped
    /// cost-volume weights with `--set volume_branch=true`, the volume branch fresh).
    #[arg(long, alias = "init-from", conflicts_with = "resume")]
    init: Option<PathBuf>,
    /// Optimizer steps in all.
    #[arg(long, default_value_t = 6000)]
    steps: u64,
    /// Learning rate after warm-up (the paper's is 8e-5 for 1.45M steps; short runs here
    /// need more).
    #[arg(long, default_value_t = 1e-3)]
    lr: f64,
    /// Linear warm-up steps.
    #[arg(long, default_value_t = 200)]
    warmup: u64,
    /// Largest global gradient norm.
    #[arg(long, default_value_t = 1.0)]
    clip: f64,
    /// Seed of the weights and samples.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Steps between checkpoints.
    #[arg(long, default_value_t = 100)]
    checkpoint_every: u64,
    /// Most input stereo pairs per sample (the paper's K).
    #[arg(long, default_value_t = 3)]
    max_pairs: usize,
    /// Always use the bin's first pair as input (switches stochastic view subsampling off;
    /// the same as `--set view_subsampling=false`).
    #[arg(long)]
    no_subsample: bool,
    /// Distance between a bin's first and last frames, metres: 8 for streets; handheld
    /// desks and rooms move centimetres per frame, so their bins are shorter (0.1 for desks,
    /// 0.5 for rooms: docs/training.md). One value for every `--data` root, or one per root
    /// in the same order [default: 8].
    #[arg(long)]
    bin_length: Vec<f64>,
    /// Read frames at this size (intrinsics scaled), e.g. real KITTI-360 at 544x144.
    #[arg(long, num_args = 2, value_names = ["WIDTH", "HEIGHT"])]
    resize: Option<Vec<u32>>,
    /// Target frames rendered per step.
    #[arg(long, default_value_t = 2)]
    targets: usize,
    /// The error the depth losses average: `metric` (the paper's L1 in metres) or
    /// `relative` (|d - d*| / d*, the evaluation's AbsRel).
    #[arg(long, default_value = "metric")]
    depth_loss: DepthError,
    /// Weight of the rendered-depth loss (default: the paper's 0.01, for metric errors).
    #[arg(long)]
    rendered_depth_weight: Option<f64>,
    /// Weight of the estimated-depth loss (default: the paper's 0.05, for metric errors).
    #[arg(long)]
    estimated_depth_weight: Option<f64>,
    /// Weight of the volume branch's occupancy loss (default 0.05; with the branch only).
    #[arg(long)]
    occupancy_weight: Option<f64>,
    /// Weight of the volume-only render's L2 on in-volume pixels (default 1.0; with the
    /// branch only).
    #[arg(long)]
    volume_render_weight: Option<f64>,
    /// Weight of the matching loss: the cost volume's own cross-entropy against the LiDAR
    /// depth, so the features match instead of the priors guessing (default 0, the paper's
    /// objective without it).
    #[arg(long)]
    matching_weight: Option<f64>,
}

/// The loss weights the flags ask for: the paper's, with the depth error and weights set.
fn loss_weights(args: &TrainArgs) -> LossWeights {
    let paper = LossWeights::default();
    LossWeights {
        depth_error: args.depth_loss,
        rendered_depth: args.rendered_depth_weight.unwrap_or(paper.rendered_depth),
        estimated_depth: args.estimated_depth_weight.unwrap_or(paper.estimated_depth),
        occupancy: args.occupancy_weight.unwrap_or(paper.occupancy),
        volume_render: args.volume_render_weight.unwrap_or(paper.volume_render),
        matching: args.matching_weight.unwrap_or(paper.matching),
        ..paper
    }
}

/// Training bins `length_m` metres long, refused unless that is a positive distance.
pub(super) fn bins_of(length_m: f64) -> Result<BinConfig> {
    if !(length_m.is_finite() && length_m > 0.0) {
        bail!("--bin-length {length_m}: a bin must span a positive distance");
    }
    Ok(BinConfig {
        length_m,
        ..BinConfig::default()
    })
}

/// The data roots the flags name, each with its bin length.
fn data_roots(args: &TrainArgs) -> Result<Vec<DataRoot>> {
    let lengths = match args.bin_length.as_slice() {
        [] => vec![BinConfig::default().length_m; args.data.len()],
        &[one] => vec![one; args.data.len()],
        many if many.len() == args.data.len() => many.to_vec(),
        many => bail!(
            "{} --bin-length values for {} --data roots: give one for all, or one per root",
            many.len(),
            args.data.len()
        ),
    };
    args.data
        .iter()
        .zip(lengths)
        .map(|(path, length_m)| {
            Ok(DataRoot {
                path: path.clone(),
                bins: bins_of(length_m)?,
            })
        })
        .collect()
}

/// Runs `train`.
pub fn run(args: &TrainArgs) -> Result<()> {
    let data = data_roots(args)?;
    let net = Config::preset(&args.preset)?.with_settings(&args.settings)?;
    let cfg = TrainConfig {
        steps: args.steps,
        lr: args.lr,
        warmup: args.warmup,
        clip: args.clip,
        seed: args.seed,
        checkpoint_every: args.checkpoint_every.max(1),
        sample: SampleConfig {
            max_pairs: args.max_pairs.max(1),
            subsample_views: net.view_subsampling && !args.no_subsample,
            targets: args.targets,
            gaussian_stride: net.gaussian_stride,
            volume: None,
        },
        loss: loss_weights(args),
        adamw: AdamWConfig::default(),
        resize: args.resize.as_ref().map(|s| (s[0], s[1])),
    };
    let mut trainer = Trainer::new(&net, cfg, &data, &args.out, args.resume)
        .with_context(|| format!("starting training in {}", args.out.display()))?;
    if let Some(init) = &args.init {
        let warm = trainer
            .load_weights(init)
            .with_context(|| format!("loading {}", init.display()))?;
        eprintln!(
            "{}: {} tensors loaded, {} fresh ({}), {} of the file unused",
            init.display(),
            warm.loaded,
            warm.fresh.len(),
            warm.fresh_prefixes().join(", "),
            warm.unused.len()
        );
    }
    eprintln!(
        "training {} on {} bins from step {} to {}",
        args.preset,
        trainer.bins(),
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
                    "loss {:.4} l2 {:.4} lpips {:.3} depth {:.3} occ {:.3} vol {:.4} {:.2} it/s",
                    r.loss,
                    r.l2,
                    r.lpips,
                    r.estimated_depth,
                    r.occupancy,
                    r.volume_l2,
                    r.steps_per_s
                ),
            )
        })?;
        Ok(trainer.step())
    })
}

/// Runs a training loop (`train` or `train-enhancer`) from step `from` to `to` under a
/// progress bar on stderr, stopping at the first SIGINT or SIGTERM (the loop checkpoints
/// after its current step); `run` gets the stop test and a `show(step, message)` callback
/// and returns the step it reached, which is printed on stdout with the exported `weights`.
/// A run stopped before `to` is an error (non-zero exit), so a script that chains phases
/// under `set -e` does not start the next phase from a half-done one.
pub(crate) fn train_under_bar(
    (from, to): (u64, u64),
    weights: &std::path::Path,
    run: impl FnOnce(&dyn Fn() -> bool, &mut dyn FnMut(u64, String)) -> Result<u64>,
) -> Result<()> {
    let stop = stop_on_signal();
    let bar = progress::bar(to as usize, "train");
    bar.set_position(from);
    let reached = run(&stop, &mut |step, message| {
        bar.set_position(step);
        bar.set_message(message);
    })?;
    bar.finish();
    println!("step {reached}: weights {}", weights.display());
    if reached < to {
        anyhow::bail!("stopped by a signal at step {reached} of {to}; the checkpoint is saved, rerun with --resume");
    }
    Ok(())
}

/// A stop test for a training loop: true once SIGINT or SIGTERM has come (the run then
/// checkpoints and ends after its current step).
fn stop_on_signal() -> impl Fn() -> bool {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc_hook(move || flag.store(true, Ordering::SeqCst));
    move || stop.load(Ordering::SeqCst)
}

/// Calls `f` on the first SIGINT or SIGTERM, from a thread of its own.
fn ctrlc_hook(f: impl FnOnce() + Send + 'static) {
    std::thread::spawn(move || {
        let Ok(rt) = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
        else {
            return;
        };
        rt.block_on(crate::cli::common::shutdown::shutdown_signal());
        f();
    });
}
