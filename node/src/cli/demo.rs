//! `stereosplat demo`: the main job on the embedded default. It generates a short synthetic
//! drive, runs the node and a replay on loopback zenoh, and leaves in one folder what a user
//! would look at: per-bin maps (3DGS PLY, SPZ or glTF binary; pose, render), the fused global
//! map (the same format, bird's-eye PNG) and a latency summary.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;
use model::kitti360::images::write_png;
use model::kitti360::Sequence;
use model::synth::SynthConfig;
use renderer::formats::MapFormat;

use super::common::drives::{cached_drive, first_sequence};
use super::common::method_args::MethodArgs;
use super::common::shutdown::shutdown_signal;
use super::common::units::rate_of;
use super::run::{OnCheckFailArg, RenderArg};
use super::view::{self, ViewFlags};
use crate::clients::loopback::{run_loopback, Received, ReceivedBin};
use crate::clients::replay::Drive;
use crate::progress;
use crate::service::latency_stats::LatencyStats;
use crate::service::NodeConfig;
use crate::store::StartMap;

/// Flags of `demo`.
#[derive(Args, Clone, Debug)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "out/demo")]
    out: PathBuf,
    /// Use this KITTI-360-layout root (its first sequence) instead of generating a drive.
    #[arg(long)]
    data: Option<PathBuf>,
    /// Seed of the generated drive.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Frames of the generated drive (10 per second).
    #[arg(long, default_value_t = 100)]
    frames: u32,
    /// Image width of the generated drive.
    #[arg(long, default_value_t = 544)]
    width: u32,
    /// Image height of the generated drive.
    #[arg(long, default_value_t = 112)]
    height: u32,
    /// Replay speed: 1 = recorded rate, 2 = twice as fast, 0 = as fast as possible.
    #[arg(long, default_value_t = 1.0)]
    rate: f64,
    /// The reconstructor, its preset, weights and settings.
    #[command(flatten)]
    method: MethodArgs,
    /// What to do with a bin whose map fails the self-check (see `run --help`).
    #[arg(long, value_enum, default_value_t = OnCheckFailArg::Sgm)]
    on_check_fail: OnCheckFailArg,
    /// Rasterizer of the per-bin renders.
    #[arg(long, value_enum, default_value_t = RenderArg::Auto)]
    renders: RenderArg,
    /// Format of the per-bin maps and the global map: `ply` (3DGS PLY), `spz` (Niantic's
    /// compressed SPZ) or `glb` (binary glTF with KHR_gaussian_splatting); docs/formats.md.
    #[arg(long, default_value_t = MapFormat::Ply)]
    format: MapFormat,
    #[command(flatten)]
    view: ViewFlags,
}

impl DemoArgs {
    /// The demo's out folder (`--out`).
    pub fn out_dir(&self) -> &std::path::Path {
        &self.out
    }
}

/// Runs the demo and prints where its outputs are.
pub fn run(args: &DemoArgs) -> Result<()> {
    let (root, name) = match &args.data {
        Some(root) => (root.clone(), first_sequence(root)?),
        None => {
            let root = args.out.join("drive");
            let config = SynthConfig {
                seed: args.seed,
                frames: args.frames,
                width: args.width,
                height: args.height,
                ..SynthConfig::default()
            };
            let name = cached_drive(&root, &config)?;
            (root, name)
        }
    };
    let sequence = Sequence::open(&root, &name)?;
    let bins_dir = args.out.join("bins");
    std::fs::create_dir_all(&bins_dir)
        .with_context(|| format!("creating {}", bins_dir.display()))?;
    let config = args.method.node_config(NodeConfig {
        on_check_fail: args.on_check_fail.into(),
        renders: args.renders.into(),
        out_dir: Some(args.out.join("map")),
        map_format: args.format,
        // Each demo is a run of its own: an earlier demo's map is kept aside, not resumed.
        start_map: StartMap::Fresh,
        checkpoint_every: 0,
        ..NodeConfig::default()
    });
    let keys = config.keys.clone();
    let bar = progress::bar(sequence.frames().len(), "replay");
    let mut write_error = None;
    let mut on_bin = |received: Received| {
        let written = match received {
            Received::Bin(bin) => write_bin(&bins_dir, &bin, args.format),
            Received::Render { bin_id, image } => {
                let path = bins_dir.join(format!("bin_{bin_id:04}_render.png"));
                write_png(&path, &image).map_err(Into::into)
            }
        };
        if let Err(e) = written {
            write_error.get_or_insert(e);
        }
    };
    let runtime = tokio::runtime::Runtime::new()?;
    let (report, view) = runtime.block_on(async {
        let (start_view, view) = view::beside(&args.view, keys).await?;
        let report = run_loopback(
            config,
            Drive::whole(&sequence),
            rate_of(args.rate)?,
            Duration::from_secs(60),
            &mut progress::hook(&bar),
            &mut on_bin,
            start_view,
        )
        .await?;
        anyhow::Ok((report, view))
    })?;
    bar.finish_and_clear();
    if let Some(e) = write_error {
        return Err(e.context("writing a bin's files"));
    }

    let stats = LatencyStats::of(&report.latencies);
    let summary = serde_json::json!({
        "sequence": name,
        "frames": report.frames,
        "bins_expected": report.bins_expected,
        "bins_received": report.bins_received,
        "global_gaussians": report.node.global_gaussians,
        "peak_rss_mib": report.peak_rss_bytes as f64 / (1 << 20) as f64,
        "latency": stats.summary(),
        "counters": report.node.counters,
    });
    let latency_path = args.out.join("latency.json");
    std::fs::write(
        &latency_path,
        serde_json::to_string_pretty(&summary)? + "\n",
    )
    .with_context(|| format!("writing {}", latency_path.display()))?;

    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "demo: {} frames of {name} -> {} of {} bins, {} Gaussians in the global map",
        report.frames, report.bins_received, report.bins_expected, report.node.global_gaussians
    )?;
    writeln!(out, "{}", stats.summary())?;
    writeln!(out, "per-bin maps:  {}", bins_dir.display())?;
    for f in [
        format!("global_map.{}", args.format),
        "global_map_bev.png".into(),
    ] {
        writeln!(
            out,
            "global map:    {}",
            args.out.join("map").join(f).display()
        )?;
    }
    writeln!(out, "latency:       {}", latency_path.display())?;
    drop(out);
    if let Some(view) = view::take(&view) {
        eprintln!("view: still serving {} (Ctrl-C to stop)", view.url());
        runtime.block_on(async {
            shutdown_signal().await;
            view.stop().await;
        });
    }
    Ok(())
}

/// Writes one bin: `bin_<id>.<ply|spz|glb>` (bin frame) and `bin_<id>_pose.json` (bin frame
/// to world, f64).
fn write_bin(dir: &Path, bin: &ReceivedBin, format: MapFormat) -> Result<()> {
    let stem = dir.join(format!("bin_{:04}", bin.bin_id));
    let map = stem.with_extension(format.extension());
    renderer::formats::save_map(&bin.gaussians, &map, format)
        .with_context(|| format!("writing {}", map.display()))?;
    let m = bin.bin_to_world;
    let pose = serde_json::json!({
        "bin_id": bin.bin_id,
        "rotation_rows": [m.matrix3.row(0).to_array(), m.matrix3.row(1).to_array(), m.matrix3.row(2).to_array()],
        "translation": m.translation.to_array(),
        "gaussians": bin.gaussians.len(),
    });
    let path = dir.join(format!("bin_{:04}_pose.json", bin.bin_id));
    std::fs::write(&path, serde_json::to_string_pretty(&pose)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
