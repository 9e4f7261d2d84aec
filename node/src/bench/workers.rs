//! `stereosplat bench workers`: how the node's bin rate grows with worker processes. A
//! generated held-out drive at KITTI-360's frame size replayed at its recorded rate
//! through a real node on loopback that runs no reconstructor itself, once per run, with
//! that many `stereosplat worker` processes (this binary), each limited to `--threads`
//! threads; a run of 0 is the node's own worker thread with the machine's threads, for
//! reference. Per run: bins opened, published and dropped, the bins per second published
//! (from the first bin's first frame to the last map), each worker's share and its time
//! per bin. JSON on stdout and in `--out` (`workers_bin<length>m.json`), with a Markdown
//! table beside it.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde::Serialize;

use super::heldout_drive::HeldoutDriveArgs;
use crate::cli::common::units::rate_of;
use crate::clients::loopback::run_loopback;
use crate::clients::replay::Drive;
use crate::pipeline::binner::BinnerConfig;
use crate::pipeline::worker::RenderWith;
use crate::progress;
use crate::service::latency_stats::{publish_span_s, LatencyStats, StageSummary};
use crate::service::{InputLimits, NodeConfig, WorkersConfig};

/// Flags of `bench workers`.
#[derive(Args, Clone, Debug)]
pub struct BenchWorkersArgs {
    #[command(flatten)]
    drive_args: HeldoutDriveArgs,
    /// Folder of the generated drive (kept between runs).
    #[arg(long, default_value = "out/bench_workers/drive")]
    drive: PathBuf,
    /// Folder for `workers.json` and `workers.md`.
    #[arg(long, default_value = "out/bench_workers")]
    out: PathBuf,
    /// Runs, one node each: how many worker processes (0: the node's own thread instead).
    #[arg(long = "workers", default_values_t = [1usize, 2])]
    runs: Vec<usize>,
    /// Threads of each worker process.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Pixels the reconstructor is given (the node's `--working-pixels`); the default,
    /// half of 1408x376 a side, is the shipped table's `tiny-scale0.5` point.
    #[arg(long, default_value_t = 704 * 188)]
    working_pixels: u64,
    /// Bins waiting for a worker at most.
    #[arg(long, default_value_t = crate::service::DEFAULT_QUEUE)]
    queue: usize,
    /// Bin length in metres (the node's `--bin-length`): shorter bins ask more bins per
    /// second of the workers at the same camera rate.
    #[arg(long, default_value_t = 8.0)]
    bin_length: f64,
}

/// One run's figures.
#[derive(Serialize)]
struct RunReport {
    workers: usize,
    bins_opened: u64,
    bins_published: u64,
    drops: u64,
    span_s: f64,
    bins_per_s: f64,
    bins_by_worker: Vec<(String, u64)>,
    model: Option<StageSummary>,
    wall_s: f64,
}

/// A worker process of this binary, stopped when dropped.
struct Spawned(Child);

impl Drop for Spawned {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `stereosplat worker` `id` listening on a free loopback port with `threads`
/// threads; returns it and its endpoint once it says it is ready.
fn spawn_worker(id: &str, threads: usize) -> Result<(Spawned, String)> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let exe = std::env::current_exe()?;
    let mut child = Command::new(exe)
        .args([
            "worker",
            "--listen",
            &endpoint,
            "--id",
            id,
            "--renders",
            "off",
        ])
        .args(["--threads", &threads.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .context("starting a worker process")?;
    let stderr = child.stderr.take().context("the worker's stderr")?;
    let spawned = Spawned(child);
    let mut lines = BufReader::new(stderr).lines();
    loop {
        match lines.next() {
            Some(Ok(line)) if line.starts_with("worker ready") => break,
            Some(Ok(_)) => {}
            _ => bail!("worker {id} ended before it was ready"),
        }
    }
    // Its later lines are not read: a worker says little (refusals, errors).
    std::thread::spawn(move || lines.for_each(drop));
    Ok((spawned, endpoint))
}

/// Runs the drive once per `--workers` and prints the reports.
pub fn run(args: &BenchWorkersArgs) -> Result<()> {
    let sequence = args.drive_args.sequence(&args.drive)?;
    let runtime = tokio::runtime::Runtime::new()?;
    let mut reports = Vec::new();
    for &n in &args.runs {
        let mut spawned = Vec::new();
        let mut connect = Vec::new();
        for i in 0..n {
            let (child, endpoint) = spawn_worker(&format!("w{i}"), args.threads)?;
            spawned.push(child);
            connect.push(endpoint);
        }
        let mut config = NodeConfig {
            binner: BinnerConfig {
                length_m: args.bin_length,
                ..BinnerConfig::default()
            },
            renders: RenderWith::Off,
            queue_capacity: args.queue,
            limits: InputLimits {
                max_working_pixels: args.working_pixels,
                ..InputLimits::default()
            },
            workers: WorkersConfig {
                local: n == 0,
                ..WorkersConfig::default()
            },
            ..NodeConfig::default()
        };
        config.transport.connect = connect;
        let label = format!("{n} workers");
        let bar = progress::bar(sequence.frames().len(), &label);
        let report = runtime.block_on(run_loopback(
            config,
            Drive::whole(&sequence),
            rate_of(1.0)?,
            Duration::from_secs(20),
            &mut progress::hook(&bar),
            &mut |_| {},
            |_| {},
        ))?;
        bar.finish_and_clear();
        drop(spawned);
        let stats = LatencyStats::of(&report.latencies);
        let span_s = publish_span_s(&report.latencies).unwrap_or(f64::NAN);
        let counters = &report.node.counters;
        let r = RunReport {
            workers: n,
            bins_opened: report.bins_expected,
            bins_published: report.node.bins_published,
            drops: counters.get("dropped/worker_queue") + counters.get("dropped/at_stop"),
            span_s,
            bins_per_s: report.node.bins_published as f64 / span_s,
            bins_by_worker: (0..n)
                .map(|i| {
                    let id = format!("w{i}");
                    let bins = counters.get(&format!("workers/bins/{id}"));
                    (id, bins)
                })
                .collect(),
            model: stats.summary().model,
            wall_s: report.wall_s,
        };
        eprintln!(
            "{label}: {} of {} bins published, {:.3} bins/s",
            r.bins_published, r.bins_opened, r.bins_per_s
        );
        reports.push(r);
    }
    let per_s = |n: usize| {
        reports
            .iter()
            .find(|r| r.workers == n)
            .map(|r| r.bins_per_s)
    };
    let out = serde_json::json!({
        "drive": args.drive_args.json(),
        "working_pixels": args.working_pixels,
        "bin_length_m": args.bin_length,
        "threads_per_worker": args.threads,
        "node_threads": rayon::current_num_threads(),
        "queue": args.queue,
        "renders": "off",
        "runs": reports,
        "two_over_one": per_s(2).zip(per_s(1)).map(|(a, b)| a / b),
    });
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let json = serde_json::to_string_pretty(&out)? + "\n";
    let stem = format!("workers_bin{}m", args.bin_length);
    std::fs::write(args.out.join(format!("{stem}.json")), &json)?;
    std::fs::write(args.out.join(format!("{stem}.md")), markdown(&reports))?;
    print!("{json}");
    Ok(())
}

fn markdown(reports: &[RunReport]) -> String {
    let mut md = String::from(
        "| worker processes | bins published / opened | dropped | bins per second | bins by worker | model ms p50 |\n\
         |---:|---:|---:|---:|---|---:|\n",
    );
    for r in reports {
        let by: Vec<String> = r
            .bins_by_worker
            .iter()
            .map(|(id, n)| format!("{id} {n}"))
            .collect();
        md += &format!(
            "| {} | {} / {} | {} | {:.3} | {} | {} |\n",
            match r.workers {
                0 => "none (the node's own thread)".to_string(),
                n => n.to_string(),
            },
            r.bins_published,
            r.bins_opened,
            r.drops,
            r.bins_per_s,
            by.join(", "),
            r.model
                .as_ref()
                .map_or("-".into(), |m| format!("{:.0}", m.p50_ms)),
        );
    }
    md
}
