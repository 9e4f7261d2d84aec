//! `stereosplat bench keep-up`: whether a node keeps up with the camera. A generated
//! held-out drive at KITTI-360's frame size replayed at its recorded rate through a real
//! node on loopback, once per run: with the latency budget `auto` over a table of operating
//! points, and with single points fixed (by default `tiny`, the default network, and the
//! table's fastest). Per run: bins opened, published and dropped (all of them, and after
//! the warm-up), the points the bins ran with, switches, the worker's time per bin, and the
//! bin-average PSNR of what was published: each published bin map rendered at its bin's
//! middle and last frames and scored against the recorded left images. JSON on stdout and
//! in `--out`, with a Markdown table beside it.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::Args;
use model::bins::{make_bins, BinConfig, BinLayout};
use model::frame::{RgbImage, Side};
use model::kitti360::Sequence;
use model::metrics::psnr;
use renderer::{Raster, RenderSettings};
use serde::Serialize;

use super::heldout_drive::HeldoutDriveArgs;
use crate::cli::common::operating_args::SHIPPED_TABLE;
use crate::cli::common::units::rate_of;
use crate::cli::run::RenderArg;
use crate::clients::loopback::{run_loopback, Received, ReceivedBin};
use crate::clients::replay::Drive;
use crate::msg::latency::BinLatency;
use crate::pipeline::operating::{Budget, GovernorConfig, OperatingConfig, OperatingTable};
use crate::progress;
use crate::service::latency_stats::{LatencyStats, StageSummary};
use crate::service::NodeConfig;

/// Flags of `bench keep-up`.
#[derive(Args, Clone, Debug)]
pub struct BenchKeepUpArgs {
    #[command(flatten)]
    drive_args: HeldoutDriveArgs,
    /// Folder for the drive (kept between runs), `keep_up.json` and `keep_up.md`.
    #[arg(long, default_value = "out/bench_keep_up")]
    out: PathBuf,
    /// The table of operating points (default: the shipped one).
    #[arg(long, default_value = SHIPPED_TABLE)]
    operating_points: PathBuf,
    /// Runs, one node each: `auto`, a budget in ms, or `fixed:POINT` (a row of the table, or
    /// `fastest`).
    #[arg(long, default_values_t = ["auto".to_string(), "fixed:tiny".to_string(), "fixed:fastest".to_string()])]
    run: Vec<String>,
    /// Seconds of the drive before drops count as steady state.
    #[arg(long, default_value_t = 10.0)]
    warmup_s: f64,
    /// Bins waiting for the worker at most.
    #[arg(long, default_value_t = crate::service::DEFAULT_QUEUE)]
    queue: usize,
    /// Rasterizer of the node's per-bin renders (worker time, as a user's node spends it).
    #[arg(long, value_enum, default_value_t = RenderArg::Auto)]
    renders: RenderArg,
}

/// One run's figures.
#[derive(Serialize)]
struct RunReport {
    run: String,
    budget: String,
    bins_opened: u64,
    bins_published: u64,
    drops: u64,
    steady_state_drops: u64,
    psnr_published: Option<f64>,
    scored_frames: usize,
    points: BTreeMap<String, u64>,
    switches: u64,
    no_point_fits: u64,
    model: Option<StageSummary>,
    render: Option<StageSummary>,
    wall_s: f64,
}

/// Runs the drive once per `--run` and prints the reports.
pub fn run(args: &BenchKeepUpArgs) -> Result<()> {
    let table = OperatingTable::load(&args.operating_points)?;
    let drive_dir = args.out.join("drive");
    let sequence = args.drive_args.sequence(&drive_dir)?;
    let runtime = tokio::runtime::Runtime::new()?;
    let mut reports = Vec::new();
    for run in &args.run {
        let operating = operating_for(run, &table)?;
        let budget = match run.starts_with("fixed:") {
            true => "none (one point)".to_string(),
            false => format!("{:?}", operating.budget),
        };
        let config = NodeConfig {
            renders: args.renders.into(),
            queue_capacity: args.queue,
            operating: Some(operating),
            ..NodeConfig::default()
        };
        let mut bins: Vec<ReceivedBin> = Vec::new();
        let bar = progress::bar(sequence.frames().len(), run);
        let report = runtime.block_on(run_loopback(
            config,
            Drive::whole(&sequence),
            rate_of(1.0)?,
            Duration::from_secs(60),
            &mut progress::hook(&bar),
            &mut |r| {
                if let Received::Bin(b) = r {
                    bins.push(*b);
                }
            },
            |_| {},
        ))?;
        bar.finish_and_clear();
        let (psnr_published, scored_frames) = score(&sequence, &bins)?;
        let stats = LatencyStats::of(&report.latencies);
        let summary = stats.summary();
        let drops = report.node.counters.get("dropped/worker_queue");
        let r = RunReport {
            run: run.clone(),
            budget,
            bins_opened: report.bins_expected,
            bins_published: report.node.bins_published,
            drops,
            steady_state_drops: drops.saturating_sub(drops_by(&report.latencies, args.warmup_s)),
            psnr_published,
            scored_frames,
            points: summary.operating_points.clone(),
            switches: report.node.counters.get("operating/switches"),
            no_point_fits: report.node.counters.get("operating/no_point_fits"),
            model: summary.model,
            render: summary.render,
            wall_s: report.wall_s,
        };
        eprintln!(
            "{run}: {} of {} bins published, {} dropped ({} after the warm-up), PSNR {:.2}",
            r.bins_published,
            r.bins_opened,
            r.drops,
            r.steady_state_drops,
            r.psnr_published.unwrap_or(f64::NAN)
        );
        reports.push(r);
    }
    let out = serde_json::json!({
        "drive": args.drive_args.json(),
        "table": {
            "path": args.operating_points.display().to_string(),
            "size": table.size,
            "source": table.source,
        },
        "threads": rayon::current_num_threads(),
        "queue": args.queue,
        "renders": format!("{:?}", args.renders).to_lowercase(),
        "warmup_s": args.warmup_s,
        "runs": reports,
    });
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let json = serde_json::to_string_pretty(&out)? + "\n";
    std::fs::write(args.out.join("keep_up.json"), &json)?;
    std::fs::write(args.out.join("keep_up.md"), markdown(&reports))?;
    print!("{json}");
    Ok(())
}

/// The operating config a `--run` value names.
fn operating_for(run: &str, table: &OperatingTable) -> Result<OperatingConfig> {
    let (table, budget) = match run.strip_prefix("fixed:") {
        Some(point) => {
            let row = match point {
                "fastest" => table.fastest(),
                name => match table.rows.iter().position(|r| r.point.name == name) {
                    Some(i) => i,
                    None => bail!("--run {run}: the table has no point `{name}`"),
                },
            };
            let one = OperatingTable::new(
                table.size,
                table.source.clone(),
                vec![table.rows[row].clone()],
            )?;
            (one, Budget::Fixed(f64::MAX))
        }
        None => (table.clone(), run.parse::<Budget>()?),
    };
    Ok(OperatingConfig {
        table,
        budget,
        governor: GovernorConfig::default(),
    })
}

/// The drops the node had counted by the last bin whose first frame arrived within
/// `warmup_s` of the first bin's.
fn drops_by(latencies: &[BinLatency], warmup_s: f64) -> u64 {
    let Some(t0) = latencies
        .iter()
        .map(|l| l.first_frame_arrival_ns)
        .filter(|&t| t > 0)
        .min()
    else {
        return 0;
    };
    let limit = t0 + (warmup_s * 1e9) as i64;
    latencies
        .iter()
        .filter(|l| l.first_frame_arrival_ns > 0 && l.first_frame_arrival_ns <= limit)
        .map(|l| l.drops)
        .max()
        .unwrap_or(0)
}

/// Bin-average PSNR of `bins`, each rendered at its bin's middle and last frames, and the
/// frames scored.
fn score(sequence: &Sequence, bins: &[ReceivedBin]) -> Result<(Option<f64>, usize)> {
    let frames = sequence.frames();
    let poses: Vec<_> = frames.iter().map(|f| f.left_to_world).collect();
    let layout = make_bins(
        &poses,
        &BinConfig {
            length_m: 8.0,
            layout: BinLayout::Consecutive,
        },
    );
    let rig = sequence.rig();
    let mut per_bin = Vec::new();
    let mut scored = 0;
    for b in bins {
        // The bin whose first frame the published pose is (the pose went through a
        // quaternion on the wire: equal within a millimetre, not bit for bit).
        let Some(bin) = layout.iter().find(|x| {
            poses[x.first]
                .translation
                .distance(b.bin_to_world.translation)
                < 1e-3
        }) else {
            continue;
        };
        let mut values = Vec::new();
        for index in [bin.centre, bin.last] {
            let camera = rig.local_camera(b.bin_to_world, poses[index], Side::Left);
            let out = Raster::Cpu.render(&b.gaussians, &camera, &RenderSettings::default())?;
            let image = RgbImage {
                width: out.width,
                height: out.height,
                data: out.rgb,
            };
            let truth = sequence.load_frame(frames[index].index)?.left;
            values.push(psnr(&image, &truth)?);
            scored += 1;
        }
        per_bin.push(values.iter().sum::<f64>() / values.len() as f64);
    }
    let mean = (!per_bin.is_empty()).then(|| per_bin.iter().sum::<f64>() / per_bin.len() as f64);
    Ok((mean, scored))
}

fn markdown(reports: &[RunReport]) -> String {
    let mut md = String::from(
        "| run | bins published / opened | dropped | dropped after warm-up | PSNR of the published | points (bins) | switches | model ms p50 |\n\
         |---|---:|---:|---:|---:|---|---:|---:|\n",
    );
    for r in reports {
        let points: Vec<String> = r.points.iter().map(|(k, v)| format!("{k} {v}")).collect();
        md += &format!(
            "| {} | {} / {} | {} | {} | {} | {} | {} | {} |\n",
            r.run,
            r.bins_published,
            r.bins_opened,
            r.drops,
            r.steady_state_drops,
            r.psnr_published.map_or("-".into(), |p| format!("{p:.2}")),
            points.join(", "),
            r.switches,
            r.model
                .as_ref()
                .map_or("-".into(), |m| format!("{:.0}", m.p50_ms)),
        );
    }
    md
}
