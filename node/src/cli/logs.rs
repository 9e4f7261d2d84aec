//! `stereosplat record` (the node's topics to an MCAP file), `stereosplat monitor` (live
//! latency percentiles) and the MCAP side of `stereosplat replay --mcap`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;

use super::progress;
use super::shutdown::shutdown_signal;
use super::zenoh_args::ZenohArgs;
use crate::bag::{BagReader, Rate};
use crate::msg::latency::BinLatency;
use crate::service::keys::{Direction, Topic, TOPICS};
use crate::service::latency_stats::bin_stages_ms;
use crate::service::{self, BagReplayOptions, LatencyStats, MonitorEvent, RecordLimits};
use crate::transport::open;

/// Flags of `record`.
#[derive(Args, Clone, Debug)]
pub struct RecordArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// The MCAP file to write (replaced if it exists).
    #[arg(long)]
    out: PathBuf,
    /// Stop after this many seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Stop after this many messages.
    #[arg(long)]
    count: Option<u64>,
}

/// Records every topic of the node (inputs and outputs) until Ctrl-C, SIGTERM, `--duration`
/// or `--count`; the file is finished in every case. Prints the messages per topic.
pub fn record(args: &RecordArgs) -> Result<()> {
    let duration = args
        .duration
        .map(|s| {
            Duration::try_from_secs_f64(s)
                .ok()
                .filter(|d| !d.is_zero())
                .with_context(|| format!("--duration must be positive seconds, not {s}"))
        })
        .transpose()?;
    let limits = RecordLimits {
        duration,
        count: args.count,
    };
    let keys = args.zenoh.keys();
    create_parent(&args.out)?;
    let runtime = tokio::runtime::Runtime::new()?;
    let summary = runtime.block_on(async {
        let session = open(&args.zenoh.transport()).await?;
        eprintln!(
            "recorder ready: {} topics under {:?} -> {}",
            keys.all().len(),
            keys.namespace,
            args.out.display()
        );
        let recorded = service::record(&session, &keys, &args.out, limits, shutdown_signal());
        anyhow::Ok(recorded.await?)
    })?;
    for (topic, count) in &summary.per_topic {
        println!("{count:>8}  {topic}");
    }
    println!(
        "{:>8}  messages in {}",
        summary.messages,
        args.out.display()
    );
    Ok(())
}

/// Flags of `replay` that only apply with `--mcap`.
#[derive(Args, Clone, Debug)]
pub struct BagReplayArgs {
    /// Publish only the node's input topics (images, camera infos, poses), to feed a node.
    #[arg(long, conflicts_with = "data")]
    inputs_only: bool,
    /// The namespace the recording was made under, if not `--namespace` (its topics are
    /// published under `--namespace`).
    #[arg(long, conflicts_with = "data")]
    bag_namespace: Option<String>,
    /// A recorded topic replayed as one of the node's: `NODE_TOPIC=RECORDED_TOPIC`, e.g.
    /// `left/image/compressed=/camera/left/image_raw/compressed` or `/tf=/tf` (repeat it;
    /// the node's topics are listed in docs/node.md).
    #[arg(
        long = "topic",
        value_name = "NODE_TOPIC=RECORDED_TOPIC",
        conflicts_with = "data"
    )]
    topics: Vec<String>,
    /// A TOML file of such pairs, one `"NODE_TOPIC" = "RECORDED_TOPIC"` a line (`--topic`
    /// flags come after it and win).
    #[arg(long, conflicts_with = "data")]
    topic_map: Option<PathBuf>,
}

impl BagReplayArgs {
    /// The topic map of `--topic-map` and `--topic`.
    fn topic_map(&self) -> Result<Vec<(String, Topic)>> {
        let mut pairs: Vec<(String, String)> = Vec::new();
        if let Some(path) = &self.topic_map {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading the topic map {}", path.display()))?;
            let table: toml::Table = text
                .parse()
                .with_context(|| format!("the topic map {}", path.display()))?;
            for (node, recorded) in table {
                let recorded = recorded.as_str().with_context(|| {
                    format!(
                        "{}: `{node}` must name a recorded topic (a string)",
                        path.display()
                    )
                })?;
                pairs.push((node, recorded.to_string()));
            }
        }
        for flag in &self.topics {
            let (node, recorded) = flag
                .split_once('=')
                .with_context(|| format!("--topic {flag}: give NODE_TOPIC=RECORDED_TOPIC"))?;
            pairs.push((node.to_string(), recorded.to_string()));
        }
        let mut map: Vec<(String, Topic)> = Vec::new();
        for (node, recorded) in pairs {
            let topic = TOPICS
                .into_iter()
                .find(|t| t.name.trim_start_matches('/') == node.trim().trim_start_matches('/'))
                .with_context(|| {
                    let names: Vec<&str> = TOPICS
                        .iter()
                        .filter(|t| t.direction == Direction::Input || t.name.starts_with('/'))
                        .map(|t| t.name)
                        .collect();
                    format!("`{node}` is not a topic of the node ({})", names.join(", "))
                })?;
            map.retain(|(r, _)| r != recorded.trim());
            map.push((recorded.trim().to_string(), topic));
        }
        Ok(map)
    }
}

/// Replays the MCAP recording at `path` onto the node's keys, with a progress bar. A recording
/// that was cut off (no summary: a killed recorder) is replayed as far as its complete chunks
/// go, with a line on stderr saying how much was recovered and how much ignored.
pub fn replay_mcap(
    zenoh: &ZenohArgs,
    path: &Path,
    args: &BagReplayArgs,
    rate: Rate,
    warmup: Duration,
) -> Result<()> {
    let (bag, recovery) = BagReader::open_or_recover(path)?;
    if let Some(recovery) = &recovery {
        eprintln!("{}: not a finished recording; {recovery}", path.display());
    }
    let options = BagReplayOptions {
        rate,
        inputs_only: args.inputs_only,
        recorded_namespace: args.bag_namespace.clone(),
        topic_map: args.topic_map()?,
    };
    let keys = zenoh.keys();
    let runtime = tokio::runtime::Runtime::new()?;
    let summary = runtime.block_on(async {
        let session = open(&zenoh.transport()).await?;
        tokio::time::sleep(warmup).await;
        let bar = progress::bar(bag.message_count() as usize, "replay");
        let mut hook = progress::hook(&bar);
        let mut on_progress = |done: u64, total: u64| hook(done as usize, total as usize);
        let replayed = service::replay_bag(&session, &keys, &bag, &options, &mut on_progress);
        let replayed = replayed.await;
        bar.finish_and_clear();
        anyhow::Ok(replayed?)
    })?;
    println!(
        "replayed {} messages of {} ({} output messages left out)",
        summary.published,
        path.display(),
        summary.skipped_outputs
    );
    for (topic, count) in &summary.unknown_topics {
        println!("skipped {count} messages on {topic} (not a topic of the node)");
    }
    for (topic, count) in &summary.wrong_types {
        eprintln!("skipped {count} messages on {topic}: not of the type of the node topic it is mapped to");
    }
    Ok(())
}

/// Flags of `monitor`.
#[derive(Args, Clone, Debug)]
pub struct MonitorArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// Stop after this many bins (default: at Ctrl-C or SIGTERM).
    #[arg(long)]
    bins: Option<u64>,
    /// Print the percentile table every this many bins (0: only at the end).
    #[arg(long, default_value_t = 10)]
    table_every: u64,
    /// Write the final latency summary here as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Prints a line per bin and the percentile table every few bins and at the end.
pub fn monitor(args: &MonitorArgs) -> Result<()> {
    let keys = args.zenoh.keys();
    let runtime = tokio::runtime::Runtime::new()?;
    let report = runtime.block_on(async {
        let session = open(&args.zenoh.transport()).await?;
        eprintln!("monitor ready: {}", keys.latency());
        let on_event = |event: &MonitorEvent, stats: &LatencyStats| match event {
            MonitorEvent::Bin(latency) => {
                println!("{}", bin_line(latency));
                if args.table_every > 0 && stats.bins().is_multiple_of(args.table_every) {
                    println!("{}", stats.summary());
                }
            }
            MonitorEvent::Diagnostics(_) => {}
            MonitorEvent::Undecodable { key } => eprintln!("undecodable message on {key}"),
        };
        let watched = service::monitor(&session, &keys, args.bins, shutdown_signal(), on_event);
        anyhow::Ok(watched.await?)
    })?;
    let summary = report.stats.summary();
    println!("{summary}");
    if let Some(d) = &report.diagnostics {
        let counters: Vec<String> = d
            .counters
            .iter()
            .map(|c| format!("{} {}", c.kind, c.count))
            .collect();
        println!("counters: {}", counters.join(", "));
    }
    if let Some(path) = &args.json {
        create_parent(path)?;
        let text = serde_json::to_string_pretty(&summary)?;
        std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// One line for a bin: its stage latencies in ms (`-` where a stamp is missing), queue,
/// counters and self-check (verdict, score, and what was done about a failure).
fn bin_line(l: &BinLatency) -> String {
    let verdict = |code: u8| match code {
        1 => "pass",
        2 => "FAIL",
        3 => "undetermined",
        _ => "not run",
    };
    let mut check = format!("check {} {:.2}", verdict(l.check_verdict), l.check_score);
    match l.check_action {
        1 => check.push_str(" (published flagged)"),
        2 => check.push_str(" (opacity lowered)"),
        3 => check.push_str(&format!(
            " -> sgm {} {:.2}",
            verdict(l.fallback_verdict),
            l.fallback_score
        )),
        _ => {}
    }
    let stages: Vec<String> = bin_stages_ms(l)
        .iter()
        .map(|(name, ms)| match ms {
            Some(ms) => format!("{name} {ms:.1}"),
            None => format!("{name} -"),
        })
        .collect();
    let point = match l.operating_point.as_str() {
        "" => String::new(),
        p => format!("point {p}; "),
    };
    format!(
        "bin {:>4}: {point}{} ms; queue {}, drops {}, bad {}; {check}",
        l.bin_id,
        stages.join(", "),
        l.queue_depth,
        l.drops,
        l.bad_messages
    )
}

/// Creates the folder `path` will be written in.
fn create_parent(path: &std::path::Path) -> Result<()> {
    match path.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(dir) => {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))
        }
        None => Ok(()),
    }
}
