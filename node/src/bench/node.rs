//! `stereosplat bench node`: a drive through the node on loopback zenoh, as JSON on stdout.
//!
//! Per replay rate: bins per second (bins published over the span from the first bin's
//! first frame to the last publish), per-stage latency percentiles from the node's own
//! latency messages, drops, and the process's resident memory: sampled every 50 frames and
//! its peak. The node, the replay and the listener share the process (three zenoh sessions
//! over loopback TCP), so memory figures cover all three.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Result;
use clap::Args;
use model::kitti360::Sequence;
use model::synth::SynthConfig;
use serde::Serialize;

use crate::cli::common::drives::{cached_drive, first_sequence};
use crate::cli::common::method_args::MethodArgs;
use crate::cli::common::operating_args::OperatingArgs;
use crate::cli::common::units::rate_of;
use crate::cli::run::RenderArg;
use crate::clients::loopback::run_loopback;
use crate::clients::replay::Drive;
use crate::fusion::FusionConfig;
use crate::pipeline::binner::BinnerConfig;
use crate::progress;
use crate::service::latency_stats::{publish_span_s, LatencyStats, LatencySummary};
use crate::service::NodeConfig;

/// Flags of `bench node`.
#[derive(Args, Clone, Debug)]
pub struct BenchNodeArgs {
    /// A KITTI-360-layout root (its first sequence); default: generate one into --cache.
    #[arg(long)]
    data: Option<PathBuf>,
    /// Where the generated drive is kept between runs.
    #[arg(long, default_value = "out/bench_node/drive")]
    cache: PathBuf,
    /// Frames of the generated drive.
    #[arg(long, default_value_t = 1000)]
    frames: u32,
    /// Image width of the generated drive.
    #[arg(long, default_value_t = 544)]
    width: u32,
    /// Image height of the generated drive.
    #[arg(long, default_value_t = 112)]
    height: u32,
    /// Replay rates to run, one node each (0 = as fast as possible, 1 = recorded rate).
    #[arg(long, default_values_t = [0.0, 1.0])]
    rate: Vec<f64>,
    /// The node's reconstructor, renders, queue and budget.
    #[command(flatten)]
    node: BenchNodeSettings,
}

/// The node settings a benchmark run sets (`bench node`, `bench drive`).
#[derive(Args, Clone, Debug)]
pub struct BenchNodeSettings {
    /// The reconstructor, its preset, weights and settings.
    #[command(flatten)]
    pub method: MethodArgs,
    /// Rasterizer of the per-bin renders.
    #[arg(long, value_enum, default_value_t = RenderArg::Auto)]
    pub renders: RenderArg,
    /// Bins waiting for the worker at most (keep newest beyond it).
    #[arg(long, default_value_t = crate::service::DEFAULT_QUEUE)]
    pub queue: usize,
    /// The global map's Gaussian budget (its memory bound).
    #[arg(long, default_value_t = FusionConfig::default().max_gaussians)]
    pub max_gaussians: usize,
    /// A latency budget and the operating points that meet it.
    #[command(flatten)]
    pub operating: OperatingArgs,
}

impl BenchNodeSettings {
    /// `base` with these settings (a calibration, when asked, goes into `out`).
    pub fn node_config(&self, base: NodeConfig, out: &Path) -> Result<NodeConfig> {
        Ok(self.method.node_config(NodeConfig {
            renders: self.renders.into(),
            queue_capacity: self.queue,
            fusion: FusionConfig {
                max_gaussians: self.max_gaussians,
                ..base.fusion
            },
            operating: self.operating.operating(out)?,
            ..base
        }))
    }

    /// The settings as JSON fields of a report.
    pub fn report(&self) -> serde_json::Value {
        serde_json::json!({
            "method": self.method.method,
            "preset": self.method.preset,
            "settings": self.method.settings,
            "renders": format!("{:?}", self.renders).to_lowercase(),
            "max_gaussians": self.max_gaussians,
            "latency_budget": self.operating.latency_budget.map(|b| format!("{b:?}")),
        })
    }
}

/// One rate's figures.
#[derive(Serialize)]
struct RunReport {
    rate: f64,
    frames: u64,
    bins_expected: u64,
    bins_published: u64,
    bins_per_second: f64,
    drops: u64,
    global_gaussians: usize,
    latency: LatencySummary,
    /// (frames replayed, MiB) every 50 frames.
    rss_mib: Vec<(u64, f64)>,
    /// Resident memory at the end minus after the first 200 frames, MiB (`null` for a
    /// drive of 200 frames or fewer: nothing to compare).
    rss_growth_after_200_frames_mib: Option<f64>,
    peak_rss_mib: f64,
    wall_s: f64,
}

/// Runs the benchmark and prints one JSON object.
pub fn run(args: &BenchNodeArgs) -> Result<()> {
    let (root, name) = drive(args)?;
    let sequence = Sequence::open(&root, &name)?;
    let runtime = tokio::runtime::Runtime::new()?;
    let mut runs = Vec::new();
    for &rate in &args.rate {
        let config = args.node.node_config(
            NodeConfig {
                binner: BinnerConfig::default(),
                ..NodeConfig::default()
            },
            &args.cache,
        )?;
        let bar = progress::bar(sequence.frames().len(), &format!("rate {rate}"));
        let report = runtime.block_on(run_loopback(
            config,
            Drive::whole(&sequence),
            rate_of(rate)?,
            Duration::from_secs(20),
            &mut progress::hook(&bar),
            &mut |_| {},
            |_| {},
        ))?;
        bar.finish_and_clear();
        let stats = LatencyStats::of(&report.latencies);
        let span_s = publish_span_s(&report.latencies);
        let mib = |b: u64| b as f64 / (1 << 20) as f64;
        let rss_200 = report.rss_samples.iter().find(|(f, _)| *f >= 200);
        let rss_end = report.rss_samples.last().filter(|(f, _)| *f > 200);
        runs.push(RunReport {
            rate,
            frames: report.frames,
            bins_expected: report.bins_expected,
            bins_published: report.node.bins_published,
            bins_per_second: span_s.map_or(0.0, |s| report.latencies.len() as f64 / s),
            drops: report.node.counters.get("dropped/worker_queue"),
            global_gaussians: report.node.global_gaussians,
            latency: stats.summary(),
            rss_mib: report
                .rss_samples
                .iter()
                .map(|&(f, b)| (f, mib(b)))
                .collect(),
            rss_growth_after_200_frames_mib: rss_200
                .zip(rss_end)
                .map(|(&(_, a), &(_, b))| mib(b) - mib(a)),
            peak_rss_mib: mib(report.peak_rss_bytes),
            wall_s: report.wall_s,
        });
    }
    let mut out = serde_json::json!({
        "sequence": name,
        "size": [sequence.rig().intrinsics.width, sequence.rig().intrinsics.height],
        "threads": std::thread::available_parallelism().map_or(1, |n| n.get()),
        "runs": runs,
    });
    with_fields(&mut out, args.node.report());
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

/// Adds the fields of the object `more` to the object `out`.
pub fn with_fields(out: &mut serde_json::Value, more: serde_json::Value) {
    if let (Some(out), serde_json::Value::Object(more)) = (out.as_object_mut(), more) {
        out.extend(more);
    }
}

/// The drive to replay: `--data`, or one generated into `--cache` (kept for later runs).
fn drive(args: &BenchNodeArgs) -> Result<(PathBuf, String)> {
    if let Some(root) = &args.data {
        return Ok((root.clone(), first_sequence(root)?));
    }
    let config = SynthConfig {
        seed: 5,
        frames: args.frames,
        width: args.width,
        height: args.height,
        ..SynthConfig::default()
    };
    Ok((args.cache.clone(), cached_drive(&args.cache, &config)?))
}
