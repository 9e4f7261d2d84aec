//! `stereosplat bench drive`: a long generated drive replayed at its recorded rate through a
//! real node on loopback, its map journaled to disk as `run` does, so the per-bin cost of a
//! growing map shows: JSON on stdout, the per-bin series as CSV and a plot of latency
//! against bin number beside it.
//!
//! Per bin (from the node's own latency messages): arrival to publish, the wait for the
//! worker, the model, the render, and everything from the model's end until the bin is
//! published (`after_model`), split into the fusion into the global map with its journal
//! record and paging (`map_fusion`) and the publishing of the bin's messages (`publish`).
//! The render runs on the worker beside them, so it is not part of `after_model`.
//!
//! Then the process's resident memory every 50 frames, and every second with whether the
//! journal was being folded into the base then ([`super::rss_trace`], `rss.csv`), so the
//! drive's memory reads apart from the compactions' transient, and summarised per minute
//! (the level and the peaks, whose spread over the minutes says whether memory stays flat);
//! the bytes the checkpoint
//! wrote (journal records and base rewrites, from the node's counters), the time to restore
//! the final checkpoint and the time to replay a journal as large as the map (the most a
//! restore can have to replay on top of its base), and how many of the published bins still
//! have Gaussians in the final map. The goals it is read against are in
//! `docs/long-drives.md`. `--laps` plays the drive several times end to end
//! ([`chain_laps`]), for an hour of driving without generating an hour of frames.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::Args;
use glam::DAffine3;
use model::kitti360::laps::chain_laps;
use model::synth::SynthConfig;
use renderer::{Gaussian, GaussianSet};
use serde::Serialize;

use super::node::{with_fields, BenchNodeSettings};
use super::rss_trace::RssTrace;
use crate::cli::common::drives::cached_sequence;
use crate::cli::common::units::{rate_of, seconds_ns};
use crate::clients::loopback::run_loopback;
use crate::clients::replay::Drive;
use crate::fusion::{AtTornTail, FusionConfig, GlobalMap, JournalWriter, Keep};
use crate::msg::latency::BinLatency;
use crate::progress;
use crate::service::NodeConfig;
use crate::store::map_files::{restore, whole_map, CHECKPOINT, JOURNAL};
use crate::store::Compaction;
use crate::store::StartMap;

/// Flags of `bench drive`.
#[derive(Args, Clone, Debug)]
pub struct BenchDriveArgs {
    /// Frames of the generated drive (10 per second of driving).
    #[arg(long, default_value_t = 4800)]
    frames: u32,
    /// Image width of the generated drive.
    #[arg(long, default_value_t = 272)]
    width: u32,
    /// Image height of the generated drive.
    #[arg(long, default_value_t = 72)]
    height: u32,
    /// Seed of the generated drive.
    #[arg(long, default_value_t = 5)]
    seed: u64,
    /// Play the generated drive this many times end to end, each lap continuing where the
    /// last one ended (the same images on new ground): 8 laps of the default drive are an
    /// hour of driving from eight minutes of generated frames.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    laps: u32,
    /// Folder for the drive (kept between runs), the node's map, `series.csv` and
    /// `latency.png`.
    #[arg(long, default_value = "out/bench_drive")]
    out: PathBuf,
    /// Replay rate (1 = recorded rate, 0 = as fast as possible).
    #[arg(long, default_value_t = 1.0)]
    rate: f64,
    /// The node's reconstructor, renders, queue and budget.
    #[command(flatten)]
    node: BenchNodeSettings,
    /// Sync the journal after every this many bins (as `run --checkpoint-every`).
    #[arg(long, default_value_t = 1)]
    checkpoint_every: u64,
    /// Fold the journal into the base at this many MiB (as `run --compact-after-mib`).
    #[arg(long, default_value_t = 64)]
    compact_after_mib: u64,
    /// Return freed memory to the system every this many seconds, arenas one per core (as
    /// `run --release-memory-every-s`; 0: the allocator's defaults).
    #[arg(long, default_value_t = 5.0)]
    release_memory_every_s: f64,
}

/// One bin's figures, milliseconds.
#[derive(Clone, Copy, Debug, Serialize)]
struct BinRow {
    bin_id: u64,
    arrival_to_publish: f64,
    wait: f64,
    model: f64,
    render: f64,
    after_model: f64,
    map_fusion: f64,
    publish: f64,
}

impl BinRow {
    fn of(l: &BinLatency) -> Self {
        let ms = |a: i64, b: i64| {
            if a > 0 && b > 0 {
                (b - a).max(0) as f64 / 1e6
            } else {
                0.0
            }
        };
        Self {
            bin_id: l.bin_id,
            arrival_to_publish: ms(l.first_frame_arrival_ns, l.publish_ns),
            wait: ms(l.first_frame_arrival_ns, l.model_start_ns),
            model: ms(l.model_start_ns, l.model_end_ns),
            render: ms(l.model_end_ns, l.render_end_ns),
            after_model: ms(l.model_end_ns, l.publish_ns),
            map_fusion: ms(l.model_end_ns, l.map_fused_ns),
            publish: ms(l.map_fused_ns, l.publish_ns),
        }
    }
}

/// Medians of a stretch of bins, milliseconds.
#[derive(Serialize)]
struct Stretch {
    bins: usize,
    arrival_to_publish_p50: f64,
    model_p50: f64,
    render_p50: f64,
    after_model_p50: f64,
    after_model_max: f64,
    map_fusion_p50: f64,
    publish_p50: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[(v.len() - 1) / 2]
}

impl Stretch {
    fn of(rows: &[BinRow]) -> Self {
        let col = |f: fn(&BinRow) -> f64| median(rows.iter().map(f).collect());
        Self {
            bins: rows.len(),
            arrival_to_publish_p50: col(|r| r.arrival_to_publish),
            model_p50: col(|r| r.model),
            render_p50: col(|r| r.render),
            after_model_p50: col(|r| r.after_model),
            after_model_max: rows.iter().map(|r| r.after_model).fold(0.0, f64::max),
            map_fusion_p50: col(|r| r.map_fusion),
            publish_p50: col(|r| r.publish),
        }
    }
}

/// Runs the benchmark and prints one JSON object.
pub fn run(args: &BenchDriveArgs) -> Result<()> {
    let drive_dir = args.out.join("drive");
    let synth = SynthConfig {
        seed: args.seed,
        frames: args.frames,
        width: args.width,
        height: args.height,
        ..SynthConfig::default()
    };
    let sequence = cached_sequence(&drive_dir, &synth)?;
    let frames = chain_laps(sequence.frames(), args.laps);
    let map_dir = args.out.join("map");
    let config = args.node.node_config(
        NodeConfig {
            out_dir: Some(map_dir.clone()),
            start_map: StartMap::Fresh,
            checkpoint_every: args.checkpoint_every,
            compaction: Compaction {
                min_bytes: args.compact_after_mib.saturating_mul(1 << 20),
            },
            release_memory_every: Duration::from_nanos(seconds_ns(
                args.release_memory_every_s,
                "--release-memory-every-s",
            )? as u64),
            ..NodeConfig::default()
        },
        &args.out,
    )?;
    // A fresh start keeps an earlier run's files aside; this benchmark's own do not pile up.
    let _ = std::fs::remove_dir_all(&map_dir);
    let runtime = tokio::runtime::Runtime::new()?;
    let bar = progress::bar(frames.len(), "drive");
    let mut trace = RssTrace::new(map_dir.join(JOURNAL));
    let mut show = progress::hook(&bar);
    let mut hook = |done: usize, total: usize| {
        trace.observe(done);
        show(done, total);
    };
    let report = runtime.block_on(run_loopback(
        config,
        Drive {
            sequence: &sequence,
            frames: &frames,
        },
        rate_of(args.rate)?,
        Duration::from_secs(30),
        &mut hook,
        &mut |_| {},
        |_| {},
    ))?;
    bar.finish_and_clear();

    let mut rows: Vec<BinRow> = report.latencies.iter().map(BinRow::of).collect();
    rows.sort_by_key(|r| r.bin_id);
    let tenth = (rows.len() / 10).max(1);
    let first = Stretch::of(&rows[..tenth.min(rows.len())]);
    let last = Stretch::of(&rows[rows.len().saturating_sub(tenth)..]);
    write_series(&args.out, &rows)?;
    trace.write_csv(&args.out.join("rss.csv"))?;

    let mib = |b: u64| b as f64 / (1 << 20) as f64;
    // Resident memory after the first minute of driving (600 frames) and its largest after.
    let minute = report.rss_samples.iter().find(|(f, _)| *f >= 600).copied();
    let later_max = report
        .rss_samples
        .iter()
        .filter(|(f, _)| *f >= 600)
        .map(|&(_, b)| b)
        .max();
    let counters = &report.node.counters;
    let rss_split = trace.split_from(600);
    let journal = counters.get("map/journal_bytes");
    let compacted = counters.get("map/compacted_bytes");
    let bins = report.node.bins_published.max(1);

    let start = Instant::now();
    let restored = restore(&map_dir, AtTornTail::Stop)?.context("the run left no checkpoint")?;
    let restore_s = start.elapsed().as_secs_f64();
    let map = restored.map;
    let replay_s = replay_whole_map(&map, &args.out.join("replay_probe"))?;
    let whole = whole_map(&map, &map_dir.join(CHECKPOINT))?;
    let mut bins_in_map: Vec<u64> = whole.iter().map(|g| g.bin_id).collect();
    bins_in_map.sort_unstable();
    bins_in_map.dedup();

    let mut out = serde_json::json!({
        "sequence": sequence.name(),
        "laps": args.laps,
        "frames": report.frames,
        "size": [args.width, args.height],
        "rate": args.rate,
        "threads": std::thread::available_parallelism().map_or(1, |n| n.get()),
        "release_memory_every_s": args.release_memory_every_s,
        "memory_releases": counters.get("memory/releases"),
        "memory_release_ms_max": counters.get("memory/release_ms_max"),
        "bins_published": report.node.bins_published,
        "drops": counters.get("dropped/worker_queue"),
        "first_tenth": first,
        "last_tenth": last,
        "after_model_last_over_first": last.after_model_p50 / first.after_model_p50.max(1e-9),
        "map_fusion_last_over_first": last.map_fusion_p50 / first.map_fusion_p50.max(1e-9),
        "publish_last_over_first": last.publish_p50 / first.publish_p50.max(1e-9),
        "rss_mib": report.rss_samples.iter().map(|&(f, b)| (f, mib(b))).collect::<Vec<_>>(),
        "rss_after_first_minute_mib": minute.map(|(_, b)| mib(b)),
        "rss_max_after_first_minute_mib": later_max.map(mib),
        "rss_growth_after_first_minute": minute.zip(later_max).map(|((_, a), b)| b as f64 / a as f64),
        "rss_each_second_after_first_minute": rss_split,
        "rss_per_minute": trace.per_minute(),
        "rss_growth_by_minute": trace.growth_after_first_minute(),
        "rss_growth_outside_compaction": minute
            .zip(rss_split.max_outside_compaction_mib)
            .map(|((_, a), b)| b / mib(a)),
        "compaction_ms_last": counters.get("map/compaction_ms"),
        "journal_bytes_per_bin": journal / bins,
        "compacted_bytes_per_bin": compacted / bins,
        "written_over_increments": (journal + compacted) as f64 / journal.max(1) as f64,
        "compactions": counters.get("map/compactions"),
        "global_gaussians": whole.len(),
        "global_gaussians_in_memory": map.len(),
        "tiles_on_disk": map.paged_tiles().len(),
        "restore_s": restore_s,
        "replay_of_a_whole_map_journal_s": replay_s,
        "bins_in_final_map": bins_in_map.len(),
        "wall_s": report.wall_s,
        "series": args.out.join("series.csv"),
        "rss_series": args.out.join("rss.csv"),
        "plot": args.out.join("latency.png"),
    });
    with_fields(&mut out, args.node.report());
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

/// Writes `series.csv` and `latency.png` (arrival to publish, model and after-model against
/// bin number) into `dir`.
fn write_series(dir: &Path, rows: &[BinRow]) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    let mut csv = String::from(
        "bin_id,arrival_to_publish_ms,wait_ms,model_ms,render_ms,after_model_ms,\
         map_fusion_ms,publish_ms\n",
    );
    for r in rows {
        csv += &format!(
            "{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3}\n",
            r.bin_id,
            r.arrival_to_publish,
            r.wait,
            r.model,
            r.render,
            r.after_model,
            r.map_fusion,
            r.publish
        );
    }
    std::fs::write(dir.join("series.csv"), csv)?;
    let series = |name: &str, f: fn(&BinRow) -> f64| model::curve::Series {
        name: name.into(),
        points: rows.iter().map(|r| (r.bin_id as f64, f(r))).collect(),
    };
    let lines = [
        series("arrival to publish", |r| r.arrival_to_publish),
        series("model", |r| r.model),
        series("after the model", |r| r.after_model),
        series("map fusion and journal", |r| r.map_fusion),
    ];
    model::curve::write_png_titled(
        &dir.join("latency.png"),
        &lines,
        ("bin", "milliseconds (log scale)"),
        900,
        500,
    )?;
    Ok(())
}

/// Seconds to restore a checkpoint whose journal adds every Gaussian `map` holds in memory to
/// an empty base (written under `dir`, removed after): the replay a restore can face on top
/// of its base when the journal is as large as the map in memory.
fn replay_whole_map(map: &GlobalMap, dir: &Path) -> Result<f64> {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir)?;
    let mut copy = GlobalMap::new(FusionConfig {
        keep: Keep::ALL,
        max_gaussians: usize::MAX,
        ..*map.config()
    })?;
    copy.save(dir.join(CHECKPOINT))?;
    // One bin holding the whole map, placed around the map's latest origin.
    let origin = map.latest_origin().unwrap_or_default();
    let mut set = GaussianSet::default();
    for (_, g) in map.gaussians() {
        set.push(Gaussian {
            mean: (g.position - origin).as_vec3(),
            log_scale: g.log_scale,
            rotation: g.rotation,
            opacity: g.opacity,
            color: g.color,
            confidence: g.confidence,
        });
    }
    let inc = copy.insert_bin(0, &set, DAffine3::from_translation(origin))?;
    let mut writer = JournalWriter::new(dir.join(JOURNAL));
    writer.append(&copy, &inc, &[], &[])?;
    writer.close_segment()?;
    let start = Instant::now();
    let replayed = restore(dir, AtTornTail::Fail)?.context("the probe's checkpoint")?;
    let seconds = start.elapsed().as_secs_f64();
    anyhow::ensure!(
        replayed.map.len() == copy.len(),
        "the probe replayed in full"
    );
    let _ = std::fs::remove_dir_all(dir);
    Ok(seconds)
}
