//! `stereosplat replay`: a KITTI-360-layout sequence onto the node's input topics, or an MCAP
//! recording (the node's own, or a robot's `ros2 bag` through a topic map) onto its topics.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;
use model::kitti360::Sequence;

use super::common::drives::first_sequence;
use super::common::units::rate_of;
use super::common::zenoh_args::ZenohArgs;
use crate::bag::{BagReader, Rate};
use crate::clients::{self, BagReplayOptions};
use crate::progress;
use crate::transport::keys::{Direction, Topic, TOPICS};
use crate::transport::open;

/// Flags of `replay`.
#[derive(Args, Clone, Debug)]
pub struct ReplayArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// Data root in the KITTI-360 layout.
    #[arg(long, required_unless_present = "mcap", conflicts_with = "mcap")]
    data: Option<PathBuf>,
    /// Sequence (default: the first under data_2d_raw).
    #[arg(long, conflicts_with = "mcap")]
    seq: Option<String>,
    /// An MCAP recording to replay instead: of the node's topics (`stereosplat record`), or
    /// a robot's `ros2 bag record` with `--topic` or `--topic-map` saying which recorded
    /// topic is which of the node's.
    #[arg(long, visible_alias = "bag")]
    mcap: Option<PathBuf>,
    #[command(flatten)]
    bag: BagReplayArgs,
    /// Speed: 1 = the recorded rate, 2 = twice as fast, 0 = as fast as possible.
    #[arg(long, default_value_t = 1.0)]
    rate: f64,
    /// As fast as possible (the same as `--rate 0`).
    #[arg(long, conflicts_with = "rate")]
    as_fast_as_possible: bool,
    /// Seconds to wait after connecting, so subscribers are in place before the first frame.
    #[arg(long, default_value_t = 1.0)]
    warmup: f64,
    /// With `--data`: exit 0 even when some frames could not be read (each is still named
    /// on stderr with its file and reason). Without it such a replay exits 1.
    #[arg(long, conflicts_with = "mcap")]
    allow_skipped: bool,
}

/// Replays a sequence onto the node's input topics, or with `--mcap` a recording onto its topics.
pub fn replay(args: &ReplayArgs) -> Result<()> {
    let rate = match args.as_fast_as_possible {
        true => Rate::AsFastAsPossible,
        false => rate_of(args.rate)?,
    };
    let warmup = Duration::from_secs_f64(args.warmup.max(0.0));
    match (&args.mcap, &args.data) {
        (Some(mcap), _) => replay_mcap(&args.zenoh, mcap, &args.bag, rate, warmup),
        (None, Some(data)) => replay_sequence(args, data, rate, warmup),
        (None, None) => anyhow::bail!("--data or --mcap is required"),
    }
}

/// Replays the sequence under `data` (`--data`).
fn replay_sequence(args: &ReplayArgs, data: &Path, rate: Rate, warmup: Duration) -> Result<()> {
    let name = match &args.seq {
        Some(s) => s.clone(),
        None => first_sequence(data)?,
    };
    let sequence = Sequence::open(data, &name)
        .with_context(|| format!("opening sequence {name} under {}", data.display()))?;
    for bad in sequence.skipped() {
        eprintln!(
            "replay: {}: frame {} is not replayed: {}",
            sequence.pose_file().display(),
            bad.index,
            bad.reason
        );
    }
    let runtime = tokio::runtime::Runtime::new()?;
    let summary = runtime.block_on(async {
        let session = open(&args.zenoh.transport()).await?;
        tokio::time::sleep(warmup).await;
        let bar = progress::bar(sequence.frames().len(), "replay");
        let keys = args.zenoh.keys();
        let s = clients::replay(&session, &keys, &sequence, rate, &mut progress::hook(&bar)).await;
        bar.finish_and_clear();
        anyhow::Ok(s?)
    })?;
    for skip in &summary.skipped {
        eprintln!("replay: frame {} skipped: {}", skip.index, skip.error);
    }
    println!(
        "replayed {} frames of {name} ({} skipped)",
        summary.frames,
        summary.skipped.len()
    );
    match (summary.skipped.first(), args.allow_skipped) {
        (Some(first), false) => anyhow::bail!(
            "{} of {} frames could not be replayed (first: frame {}: {}); \
             --allow-skipped replays the rest and exits 0",
            summary.skipped.len(),
            sequence.frames().len(),
            first.index,
            first.error
        ),
        _ => Ok(()),
    }
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
        let replayed = clients::replay_bag(&session, &keys, &bag, &options, &mut on_progress);
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
