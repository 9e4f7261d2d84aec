//! Recording the node's topics (inputs and outputs) to an MCAP file that ROS 2 tools open:
//! channel topic `/<namespace>/<topic>` (`/tf`, `/tf_static`), the message type's complete
//! `ros2msg` definition as schema, the QoS profile as rosbag2's `offered_qos_profiles`,
//! payloads stored verbatim as `cdr`.

use std::collections::BTreeMap;
use std::future::Future;
use std::path::Path;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use tokio::sync::mpsc;
use zenoh::sample::Sample;
use zenoh::Session;

use crate::bag::{offered_qos_profiles, BagError, BagWriter, ChannelInfo, CDR};
use crate::msg::schema::ros2msg;
use crate::transport::keys::{Keys, Topic};
use crate::transport::TransportError;

/// Why a recording or an MCAP replay failed.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// Subscribing or publishing.
    #[error(transparent)]
    Transport(#[from] TransportError),
    /// Writing or reading the MCAP file.
    #[error(transparent)]
    Bag(#[from] BagError),
    /// Declaring the replay's publishers or publishing.
    #[error(transparent)]
    Outlet(#[from] crate::transport::OutletError),
}

/// A zenoh error as a [`TransportError`].
pub(super) fn zenoh_error(e: zenoh::Error) -> TransportError {
    TransportError::Zenoh(e.to_string())
}

/// When a recording stops on its own (it always stops when the `stop` future completes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RecordLimits {
    /// Stop this long after the subscribers are in place.
    pub duration: Option<Duration>,
    /// Stop after writing this many messages.
    pub count: Option<u64>,
}

/// What a recording wrote.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RecordSummary {
    /// Messages written.
    pub messages: u64,
    /// Messages written per channel topic (`/<namespace>/<topic>`); topics without messages
    /// are left out.
    pub per_topic: BTreeMap<String, u64>,
}

/// The MCAP channel a topic of the node is recorded on: topic `/` + its name under the
/// namespace, schema the message type's ROS 2 name and complete `ros2msg` definition, `cdr`
/// payloads, the topic's QoS profile as rosbag2's `offered_qos_profiles`.
pub fn channel_of(keys: &Keys, topic: Topic) -> ChannelInfo {
    ChannelInfo {
        topic: format!("/{}", keys.topic_name(topic)),
        schema_name: topic.kind.ros_name().to_string(),
        schema_text: ros2msg(topic.kind),
        message_encoding: CDR.to_string(),
        offered_qos: offered_qos_profiles(&topic.qos),
    }
}

/// While recording, the chunk being written is closed and handed to the operating system at
/// least this often, so a recorder killed with -9 loses at most about this much.
const FLUSH_EVERY: Duration = Duration::from_secs(1);

/// One sample as the recorder received it.
struct Received {
    channel: usize,
    log_time_ns: u64,
    publish_time_ns: u64,
    payload: Vec<u8>,
}

/// Nanoseconds since the Unix epoch now.
fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Records every topic of `keys` from `session` into a new MCAP file at `path` until `stop`
/// completes or a limit is reached; then stops subscribing, writes what was already received
/// (within the count limit) and finishes the file (summary and index), also when stopped early.
/// Every second (`FLUSH_EVERY`) the chunk in progress is closed and flushed, so a killed
/// recorder leaves a file whose complete chunks hold all but the last second
/// (`crate::bag::BagReader::recover`). Log time is the receive time; publish time is the
/// sample's zenoh timestamp when it has one, else the receive time; the sequence counts per
/// channel from 1.
pub async fn record(
    session: &Session,
    keys: &Keys,
    path: &Path,
    limits: RecordLimits,
    stop: impl Future<Output = ()>,
) -> Result<RecordSummary, LogError> {
    let writer = BagWriter::create(path)?;
    let topics = keys.all();
    let channels: Vec<ChannelInfo> = topics.iter().map(|&(_, t)| channel_of(keys, t)).collect();
    let (tx, mut rx) = mpsc::unbounded_channel();
    let mut subscribers = Vec::with_capacity(topics.len());
    for (channel, (key, _)) in topics.into_iter().enumerate() {
        let tx = tx.clone();
        let on_sample = move |sample: Sample| {
            let log_time_ns = now_ns();
            let publish_time_ns = sample
                .timestamp()
                .map_or(log_time_ns, |t| t.get_time().as_nanos());
            // The receiver is gone only after the recording stopped.
            let _ = tx.send(Received {
                channel,
                log_time_ns,
                publish_time_ns,
                payload: sample.payload().to_bytes().into_owned(),
            });
        };
        let subscriber = session
            .declare_subscriber(key)
            .callback(on_sample)
            .await
            .map_err(zenoh_error)?;
        subscribers.push(subscriber);
    }
    drop(tx);

    let mut recording = Recording {
        writer,
        channels: &channels,
        sequences: vec![0; channels.len()],
        summary: RecordSummary::default(),
        count: limits.count,
    };
    let deadline = async {
        match limits.duration {
            Some(d) => tokio::time::sleep(d).await,
            None => std::future::pending().await,
        }
    };
    tokio::pin!(stop, deadline);
    let mut flush = tokio::time::interval(FLUSH_EVERY);
    flush.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    while !recording.full() {
        tokio::select! {
            _ = &mut stop => break,
            _ = &mut deadline => break,
            _ = flush.tick() => recording.writer.flush()?,
            received = rx.recv() => match received {
                Some(r) => recording.write(r)?,
                None => break,
            },
        }
    }
    // Stop receiving, then keep what already arrived.
    drop(subscribers);
    while let Ok(r) = rx.try_recv() {
        if recording.full() {
            break;
        }
        recording.write(r)?;
    }
    recording.writer.finish()?;
    Ok(recording.summary)
}

/// The state of a recording in progress.
struct Recording<'a> {
    writer: BagWriter,
    channels: &'a [ChannelInfo],
    sequences: Vec<u32>,
    summary: RecordSummary,
    count: Option<u64>,
}

impl Recording<'_> {
    /// Whether the count limit is reached.
    fn full(&self) -> bool {
        self.count.is_some_and(|n| self.summary.messages >= n)
    }

    /// Writes one received sample.
    fn write(&mut self, r: Received) -> Result<(), BagError> {
        let channel = &self.channels[r.channel];
        let sequence = &mut self.sequences[r.channel];
        *sequence = sequence.wrapping_add(1);
        self.writer.write(
            channel,
            r.log_time_ns,
            r.publish_time_ns,
            *sequence,
            &r.payload,
        )?;
        self.summary.messages += 1;
        *self
            .summary
            .per_topic
            .entry(channel.topic.clone())
            .or_default() += 1;
        Ok(())
    }
}
