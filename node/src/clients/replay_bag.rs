//! Replaying an MCAP recording onto zenoh: each message's payload goes out verbatim on the
//! key of its topic (so its header keeps the stamp it was recorded with), at the recorded
//! pace (or a multiple of it, or as fast as possible). A recording of the node's own topics
//! ([`super::record()`]) replays by their names; a robot's `ros2 bag record` MCAP replays
//! through a topic map (which recorded topic is which of the node's inputs), each mapped
//! channel's type checked against the topic's: a channel of another type is skipped and
//! counted, never published as the wrong message.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use zenoh::Session;

use super::record::LogError;
use crate::bag::{BagReader, Pacer, Rate};
use crate::transport::keys::{Direction, Keys, Topic, TOPICS};
use crate::transport::Outlet;

/// How to replay a recording.
#[derive(Clone, Debug, PartialEq)]
pub struct BagReplayOptions {
    /// Pace.
    pub rate: Rate,
    /// Publish only the node's input topics (images, camera infos, poses), to feed a node.
    pub inputs_only: bool,
    /// The namespace the recording was made under, when it is not the namespace of the keys
    /// the messages are published on (`None`: the same).
    pub recorded_namespace: Option<String>,
    /// Recorded topics (as the bag names them, e.g. `/camera/left/image_raw/compressed`)
    /// published as one of the node's topics; they take precedence over the names.
    pub topic_map: Vec<(String, Topic)>,
}

/// What an MCAP replay did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BagReplaySummary {
    /// Messages published.
    pub published: u64,
    /// Messages of output topics left out by [`BagReplayOptions::inputs_only`].
    pub skipped_outputs: u64,
    /// Messages on channels that are not one of the node's topics, per channel topic.
    pub unknown_topics: BTreeMap<String, u64>,
    /// Messages on mapped channels whose type is not their node topic's, per channel topic.
    pub wrong_types: BTreeMap<String, u64>,
}

/// Publishes every message of `bag` in log-time order on `session`: a channel whose topic
/// is `/<recorded namespace>/<name>` for a name of the node's topic table goes to that
/// topic's key under `keys` (in ROS 2 mode with rmw_zenoh's attachment, as the publisher
/// node `stereosplat_replay`); other channels are skipped and counted. Puts block rather
/// than drop when zenoh's queues are full, so a fast replay loses nothing.
/// `progress(done, total)` is called after each message.
pub async fn replay_bag(
    session: &Session,
    keys: &Keys,
    bag: &BagReader,
    options: &BagReplayOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<BagReplaySummary, LogError> {
    let recorded = Keys::with_mode(
        options
            .recorded_namespace
            .clone()
            .unwrap_or_else(|| keys.namespace.clone()),
        keys.mode,
    );
    // A mapped topic is an input of this replay whatever its direction (a robot's `/tf`).
    let is_mapped = |t: &Topic| options.topic_map.iter().any(|(_, m)| m == t);
    let published: Vec<_> = TOPICS
        .into_iter()
        .filter(|t| !options.inputs_only || t.direction == Direction::Input || is_mapped(t))
        .collect();
    let outlet = Outlet::declare(session, keys, "stereosplat_replay", &published, &[]).await?;
    let first_ns = bag.time_range().map_or(0, |(first, _)| first);
    let pacer = Pacer::new(options.rate, Instant::now(), first_ns)?;
    let total = bag.message_count();
    let mut summary = BagReplaySummary::default();
    for (done, message) in bag.messages().enumerate() {
        let message = message?;
        let topic_name = &message.channel.topic;
        let mapped = options
            .topic_map
            .iter()
            .find(|(name, _)| name.trim_start_matches('/') == topic_name.trim_start_matches('/'))
            .map(|&(_, t)| t);
        if mapped.is_some_and(|t| message.channel.schema_name != t.kind.ros_name()) {
            *summary.wrong_types.entry(topic_name.clone()).or_default() += 1;
            progress(done as u64 + 1, total);
            continue;
        }
        let topic = mapped.or_else(|| {
            TOPICS
                .into_iter()
                .find(|&t| topic_name.strip_prefix('/') == Some(recorded.topic_name(t).as_str()))
        });
        match topic {
            None => {
                *summary
                    .unknown_topics
                    .entry(topic_name.clone())
                    .or_default() += 1
            }
            Some(t)
                if options.inputs_only && t.direction == Direction::Output && !is_mapped(&t) =>
            {
                summary.skipped_outputs += 1
            }
            Some(t) => {
                let delay = pacer.delay(message.log_time_ns, Instant::now());
                if !delay.is_zero() {
                    tokio::time::sleep(delay).await;
                }
                outlet.put(t, message.payload).await?;
                summary.published += 1;
            }
        }
        progress(done as u64 + 1, total);
    }
    // Let the last samples leave before the caller closes the session.
    tokio::time::sleep(Duration::from_millis(100)).await;
    Ok(summary)
}
