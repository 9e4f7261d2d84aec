//! `stereosplat bench model`: the learned reconstructor per preset on this machine, as JSON on
//! stdout: milliseconds per reconstruction of one stereo pair (median and min over timed runs
//! after warm-up), the process's peak resident memory so far (with `--preset all`, the largest
//! of the presets run so far: run one preset per process for each alone), parameters and
//! Gaussians emitted. A preset without shipped weights runs untrained (`"weights":
//! "untrained"`): its time and memory are those of the trained network, its Gaussian count is
//! not. `--set volume_branch=true` runs the preset with the 3D-volume branch: the report gives
//! each branch's median milliseconds and output Gaussians (`cost_volume_*`, `volume_*`);
//! shipped weights without the branch's tensors load for the cost-volume part and the branch
//! runs untrained (`"weights": "<file> + untrained volume branch"`). Each report also times the
//! triplane encoder alone (`volume_encoder_*`: untrained, on features of the cost-volume
//! branch's shape at stride 4, with the pair's cameras). `--set device=cuda` runs the network
//! on the GPU (a build with the `cuda` feature). `--preset sgm` times the classical baseline
//! (`model::baseline`, default settings) on the same generated pair instead: milliseconds,
//! disparity levels searched, Gaussians and peak memory.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use candle_core::Tensor;
use clap::Args;
use model::baseline::{rectified_baseline, SgmReconstructor};
use model::frame::Side;
use model::kitti360::Sequence;
use model::net::volume::TriplaneEncoder;
use model::net::{
    default_weights, weights_preset, BranchReport, Config, LearnedReconstructor, COST_STRIDE,
    PRESETS,
};
use model::reconstruct::{Reconstructor, StereoView};
use model::synth::SynthConfig;
use serde::Serialize;

use crate::cli::common::drives::cached_drive;
use crate::memory::peak_rss_bytes;

/// Flags of `bench model`.
#[derive(Args, Clone, Debug)]
pub struct BenchModelArgs {
    /// Preset to measure, `all`, or `sgm` (the classical baseline).
    #[arg(long, default_value = model::methods::DEFAULT_PRESET)]
    preset: String,
    /// Change a preset setting, `KEY=VALUE` (repeatable), e.g. `--set volume_branch=true`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    settings: Vec<String>,
    /// Image width of the stereo pair (the paper's is 544).
    #[arg(long, default_value_t = 544)]
    width: u32,
    /// Image height (the paper's is 112).
    #[arg(long, default_value_t = 112)]
    height: u32,
    /// Timed runs.
    #[arg(long, default_value_t = 10)]
    runs: usize,
    /// Untimed runs first.
    #[arg(long, default_value_t = 2)]
    warmup: usize,
    /// Where the generated pair is kept between runs.
    #[arg(long, default_value = "out/bench_model/drive")]
    cache: PathBuf,
}

#[derive(Serialize)]
struct PresetReport {
    preset: String,
    /// Where the network ran (`--set device=...`).
    device: String,
    weights: String,
    width: u32,
    height: u32,
    threads: usize,
    parameters: usize,
    median_ms: f64,
    min_ms: f64,
    runs: usize,
    gaussians: usize,
    peak_rss_mib: f64,
    volume_encoder_median_ms: f64,
    volume_encoder_min_ms: f64,
    volume_encoder_parameters: usize,
    volume_branch: bool,
    cost_volume_median_ms: f64,
    volume_median_ms: f64,
    /// The `auto_depth_range` fit (SGM on the first pair), median ms; 0 when off.
    range_fit_median_ms: f64,
    cost_volume_gaussians: usize,
    volume_gaussians: usize,
}

/// Median and min milliseconds, over `runs` after `warmup`, of `f`.
fn time_runs(warmup: usize, runs: usize, mut f: impl FnMut() -> Result<()>) -> Result<(f64, f64)> {
    let mut times = Vec::with_capacity(runs);
    for i in 0..warmup + runs {
        let start = Instant::now();
        f()?;
        if i >= warmup {
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    times.sort_by(f64::total_cmp);
    Ok((
        times.get(times.len() / 2).copied().unwrap_or(f64::NAN),
        times.first().copied().unwrap_or(f64::NAN),
    ))
}

/// What `bench model --preset sgm` prints.
#[derive(Serialize)]
struct SgmReport {
    preset: &'static str,
    width: u32,
    height: u32,
    threads: usize,
    /// Disparity levels searched (the rig- and width-derived range).
    levels: usize,
    median_ms: f64,
    min_ms: f64,
    runs: usize,
    gaussians: usize,
    peak_rss_mib: f64,
}

/// Times the SGM baseline with its default settings on `view` and prints its report.
fn bench_sgm(args: &BenchModelArgs, view: &StereoView<'_>) -> Result<()> {
    let mut sgm = SgmReconstructor::default();
    let baseline = rectified_baseline(view)?;
    let levels = sgm.config.levels_for(
        view.left.width,
        Some((view.left_camera.intrinsics.fx, baseline)),
    );
    let mut gaussians = 0;
    let (median_ms, min_ms) = time_runs(args.warmup, args.runs, || {
        gaussians = sgm.reconstruct(&[*view])?.len();
        Ok(())
    })?;
    let report = SgmReport {
        preset: "sgm",
        width: args.width,
        height: args.height,
        threads: rayon::current_num_threads(),
        levels,
        median_ms,
        min_ms,
        runs: args.runs,
        gaussians,
        peak_rss_mib: peak_rss_bytes() as f64 / (1 << 20) as f64,
    };
    println!("{}", serde_json::to_string(&report)?);
    Ok(())
}

/// The untrained triplane encoder of `cfg` on random view features of the cost-volume
/// branch's shape for `cameras` (inference kernels: its weights are plain tensors, so no
/// gradient is tracked): median and min milliseconds and its parameter count.
fn time_volume_encoder(
    cfg: &Config,
    cameras: &[renderer::Camera],
    args: &BenchModelArgs,
) -> Result<(f64, f64, usize)> {
    let (encoder, parameters) = TriplaneEncoder::untrained(cfg)?;
    let (h, w) = (
        (args.height as usize).div_ceil(COST_STRIDE),
        (args.width as usize).div_ceil(COST_STRIDE),
    );
    let device = cfg.device.open()?;
    let features = Tensor::randn(0f32, 1.0, (cameras.len(), cfg.cost_channels, h, w), &device)?;
    let (median, min) = time_runs(args.warmup, args.runs, || {
        encoder.forward(None, &features, cameras, COST_STRIDE)?;
        // A GPU queues the work: wait for it, so the time is the pass's.
        device.synchronize()?;
        Ok(())
    })?;
    Ok((median, min, parameters))
}

/// Runs the benchmark.
pub fn run(args: &BenchModelArgs) -> Result<()> {
    let names: Vec<&str> = match args.preset.as_str() {
        // The networks: a `-plus` preset is its base network with the progressive pass, which
        // `bench node` and `bench pareto` time (this times the network alone).
        "all" => PRESETS
            .iter()
            .copied()
            .filter(|p| weights_preset(p) == *p)
            .collect(),
        one => vec![one],
    };
    let config = SynthConfig {
        frames: 2,
        width: args.width,
        height: args.height,
        ..SynthConfig::default()
    };
    let name = cached_drive(&args.cache, &config)?;
    let sequence = Sequence::open(&args.cache, &name)?;
    let pose = sequence.frames()[0].left_to_world;
    let frame = sequence.load_frame(sequence.frames()[0].index)?;
    let rig = sequence.rig();
    let view = StereoView {
        left: &frame.left,
        right: &frame.right,
        left_camera: rig.local_camera(pose, pose, Side::Left),
        right_camera: rig.local_camera(pose, pose, Side::Right),
    };
    if args.preset == "sgm" {
        return bench_sgm(args, &view);
    }
    for name in names {
        let cfg = Config::preset(name)?.with_settings(&args.settings)?;
        let path = default_weights(name);
        let (mut rec, weights) = if model::assets::exists(&path) {
            let (rec, warm) = LearnedReconstructor::warm_start(&cfg, &path)
                .with_context(|| format!("loading {}", path.display()))?;
            let weights = match warm.fresh.is_empty() {
                true => path.display().to_string(),
                false => format!(
                    "{} + untrained {}",
                    path.display(),
                    warm.fresh_prefixes().join(", ")
                ),
            };
            (rec, weights)
        } else {
            (
                LearnedReconstructor::untrained(&cfg)?,
                "untrained".to_string(),
            )
        };
        let mut gaussians = 0;
        let mut branches = Vec::new();
        let (median_ms, min_ms) = time_runs(args.warmup, args.runs, || {
            gaussians = rec.reconstruct(&[view])?.len();
            branches.extend(rec.last_report());
            Ok(())
        })?;
        let median = |f: &dyn Fn(&BranchReport) -> f64| {
            let mut v: Vec<f64> = branches.iter().skip(args.warmup).map(f).collect();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
        };
        let last = branches.last().copied().unwrap_or_default();
        let (volume_median, volume_min, volume_parameters) =
            time_volume_encoder(&cfg, &[view.left_camera, view.right_camera], args)?;
        let report = PresetReport {
            preset: name.to_string(),
            device: String::from(cfg.device),
            weights,
            width: args.width,
            height: args.height,
            threads: rayon::current_num_threads(),
            parameters: rec.parameters(),
            median_ms,
            min_ms,
            runs: args.runs,
            gaussians,
            peak_rss_mib: peak_rss_bytes() as f64 / (1 << 20) as f64,
            volume_encoder_median_ms: volume_median,
            volume_encoder_min_ms: volume_min,
            volume_encoder_parameters: volume_parameters,
            volume_branch: cfg.volume_branch,
            cost_volume_median_ms: median(&|b| b.cost_volume_ms),
            volume_median_ms: median(&|b| b.volume_ms),
            range_fit_median_ms: median(&|b| b.range_fit_ms),
            cost_volume_gaussians: last.cost_volume_gaussians,
            volume_gaussians: last.volume_gaussians,
        };
        println!("{}", serde_json::to_string(&report)?);
    }
    Ok(())
}
