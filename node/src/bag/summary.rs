//! Reading and checking the index of a finished MCAP file: magic bytes, footer, summary CRC,
//! channels, statistics and chunk indexes. Everything [`super::BagReader`] needs before the
//! first message.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{Read, Seek};
use std::path::Path;
use std::sync::Arc;

use mcap::records::{op, ChunkIndex};
use mcap::sans_io::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use mcap::MAGIC;

use super::records::{le_u64, read_at, summary_records_fit};
use super::{BagError, ChannelInfo, SCHEMA_ENCODING};

/// One channel of a bag and how many messages it holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelSummary {
    /// The channel.
    pub info: Arc<ChannelInfo>,
    /// Its number of messages, per the bag's statistics.
    pub message_count: u64,
}

/// Footer record (opcode, length, summary start, summary offset start, CRC) and end magic.
const FOOTER_AND_MAGIC: u64 = 1 + 8 + 8 + 8 + 4 + 8;
/// Bytes from the end of the file to the footer's CRC field (the CRC covers what precedes it).
const CRC_FROM_END: u64 = 4 + 8;

/// What a finished bag says about itself in its summary section (or, for a cut-off one, what
/// [`super::recover`] found in its complete chunks).
pub(super) struct Index {
    /// Channels in id order.
    pub channels: Vec<ChannelSummary>,
    /// Channels by MCAP channel id, for the messages.
    pub by_id: HashMap<u16, Arc<ChannelInfo>>,
    /// Chunk indexes in the order a log-time reader visits them.
    pub chunks: Vec<ChunkIndex>,
    /// Messages in the file, per the statistics record.
    pub message_count: u64,
    /// First and last log time, `None` for a bag without messages.
    pub time_range: Option<(u64, u64)>,
}

/// Reads the index of the file `file` of `file_len` bytes at `path`.
pub(super) fn read_index(path: &Path, file: &File, file_len: u64) -> Result<Index, BagError> {
    let corrupt = |offset, reason: String| BagError::Corrupt {
        path: path.to_path_buf(),
        offset,
        reason,
    };
    let unindexed = |missing: &str| BagError::Unindexed {
        path: path.to_path_buf(),
        missing: missing.into(),
    };
    let magic_len = MAGIC.len() as u64;
    if file_len < magic_len + FOOTER_AND_MAGIC {
        return Err(corrupt(
            file_len,
            format!("only {file_len} bytes, too short for an MCAP file"),
        ));
    }
    if read_at(path, file, 0, MAGIC.len())? != MAGIC {
        return Err(corrupt(0, "no MCAP magic at the start".into()));
    }
    let footer_at = file_len - FOOTER_AND_MAGIC;
    let tail = read_at(path, file, footer_at, FOOTER_AND_MAGIC as usize)?;
    // Footer: opcode (1), record length (8), summary start (8), summary offset start (8),
    // summary CRC (4).
    let (footer, end_magic) = tail.split_at(tail.len() - MAGIC.len());
    if end_magic != MAGIC {
        return Err(corrupt(
            file_len - magic_len,
            "no MCAP magic at the end (truncated, or the recording was not finished)".into(),
        ));
    }
    if footer[0] != op::FOOTER || le_u64(&footer[1..9]) != 20 {
        return Err(corrupt(
            footer_at,
            "no footer record before the end magic".into(),
        ));
    }
    let summary_start = le_u64(&footer[9..17]);
    let summary_crc = u32::from_le_bytes([footer[25], footer[26], footer[27], footer[28]]);
    if summary_start == 0 {
        return Err(unindexed("no summary section"));
    }
    if summary_start < magic_len || summary_start > footer_at {
        return Err(corrupt(
            footer_at,
            format!("footer points to a summary at byte {summary_start}, outside the file"),
        ));
    }
    // The summary section and the footer up to its CRC field: what the CRC covers.
    let covered = read_at(
        path,
        file,
        summary_start,
        (file_len - CRC_FROM_END - summary_start) as usize,
    )?;
    if summary_crc != 0 {
        let calculated = crc32fast::hash(&covered);
        if calculated != summary_crc {
            return Err(corrupt(
                summary_start,
                format!("summary CRC is {calculated:08x}, footer says {summary_crc:08x}"),
            ));
        }
    }
    // The library's summary reader parses every record it meets, reserving what their
    // strings claim: each length is checked first.
    let section = &covered[..(footer_at - summary_start) as usize];
    if let Err((at, reason)) = summary_records_fit(section) {
        return Err(corrupt(summary_start + at as u64, reason));
    }
    let summary = read_summary(file, file_len)
        .map_err(|source| BagError::Format {
            path: path.to_path_buf(),
            place: format!("summary section at byte {summary_start}"),
            source,
        })?
        .ok_or_else(|| unindexed("no summary section"))?;
    let stats = summary
        .stats
        .ok_or_else(|| unindexed("no statistics record in the summary"))?;
    if summary.chunk_indexes.is_empty() && stats.message_count > 0 {
        return Err(unindexed("messages but no chunk index"));
    }
    Index::new(
        path,
        &summary.channels,
        &stats.channel_message_counts,
        summary.chunk_indexes,
        stats.message_count,
        (stats.message_count > 0).then_some((stats.message_start_time, stats.message_end_time)),
    )
}

impl Index {
    /// The index of `channels` (by MCAP id) with their message `counts`, and `chunks`
    /// (sorted here into log-time visiting order); errors on a channel without a `ros2msg`
    /// schema.
    pub(super) fn new(
        path: &Path,
        channels: &HashMap<u16, Arc<mcap::Channel<'static>>>,
        counts: &BTreeMap<u16, u64>,
        mut chunks: Vec<ChunkIndex>,
        message_count: u64,
        time_range: Option<(u64, u64)>,
    ) -> Result<Self, BagError> {
        let mut ids: Vec<u16> = channels.keys().copied().collect();
        ids.sort_unstable();
        let mut summaries = Vec::with_capacity(ids.len());
        let mut by_id = HashMap::with_capacity(ids.len());
        for id in ids {
            let info = Arc::new(channel_info(path, &channels[&id])?);
            summaries.push(ChannelSummary {
                info: Arc::clone(&info),
                message_count: counts.get(&id).copied().unwrap_or(0),
            });
            by_id.insert(id, info);
        }
        chunks.sort_by_key(|c| (c.message_start_time, c.chunk_start_offset));
        Ok(Self {
            channels: summaries,
            by_id,
            chunks,
            message_count,
            time_range,
        })
    }
}

/// Runs the library's summary reader over `file`.
fn read_summary(mut file: &File, file_len: u64) -> mcap::McapResult<Option<mcap::Summary>> {
    let options = SummaryReaderOptions::default().with_file_size(file_len);
    let mut reader = SummaryReader::new_with_options(options);
    while let Some(event) = reader.next_event() {
        match event? {
            SummaryReadEvent::ReadRequest(need) => {
                let read = file.read(reader.insert(need))?;
                reader.notify_read(read);
            }
            SummaryReadEvent::SeekRequest(to) => reader.notify_seeked(file.seek(to)?),
        }
    }
    Ok(reader.finish())
}

/// The [`ChannelInfo`] of an MCAP channel with a `ros2msg` schema.
fn channel_info(path: &Path, channel: &mcap::Channel) -> Result<ChannelInfo, BagError> {
    let unsupported = |reason: String| BagError::Channel {
        path: path.to_path_buf(),
        topic: channel.topic.clone(),
        reason,
    };
    let schema = channel
        .schema
        .as_ref()
        .ok_or_else(|| unsupported("has no schema".into()))?;
    if schema.encoding != SCHEMA_ENCODING {
        return Err(unsupported(format!(
            "schema encoding is {:?}, only {SCHEMA_ENCODING:?} is supported",
            schema.encoding
        )));
    }
    let schema_text = String::from_utf8(schema.data.to_vec())
        .map_err(|_| unsupported("schema text is not UTF-8".into()))?;
    Ok(ChannelInfo {
        topic: channel.topic.clone(),
        schema_name: schema.name.clone(),
        schema_text,
        message_encoding: channel.message_encoding.clone(),
        offered_qos: channel
            .metadata
            .get(super::writer::QOS_KEY)
            .cloned()
            .unwrap_or_default(),
    })
}
