//! Reading what a cut-off recording holds: a recorder killed before it wrote the summary
//! leaves an MCAP file with no footer and no index, but every chunk it finished is whole
//! and carries its own CRC. This walks the data section record by record from the start,
//! keeps the schemas, channels and complete chunks (CRC checked) it meets, and stops at the
//! first record that is cut off, damaged or claims more than it holds (a string or a chunk
//! size, checked before the `mcap` crate parses the record); the index it builds serves
//! [`super::BagReader`]'s usual log-time reading of the recovered part.

use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::fs::File;
use std::path::Path;
use std::sync::Arc;

use mcap::records::{op, ChunkIndex, Record};
use mcap::MAGIC;

use super::records::{
    chunk_sizes_fit, claims_fit, compression_name_fits, for_each_record, le_u64, read_at,
    MAX_CHUNK_BYTES,
};
use super::summary::Index;
use super::BagError;

/// What [`super::BagReader::recover`] found in a cut-off recording.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Recovery {
    /// Messages in the complete chunks: what can be read back.
    pub messages: u64,
    /// Complete chunks kept.
    pub chunks: u64,
    /// Bytes from the start of the file to the end of the last complete record.
    pub readable_bytes: u64,
    /// Bytes after that, left out.
    pub ignored_bytes: u64,
    /// Why the walk stopped there.
    pub stopped: String,
}

impl fmt::Display for Recovery {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "recovered {} messages in {} complete chunks ({} bytes); ignored the last {} bytes: {}",
            self.messages, self.chunks, self.readable_bytes, self.ignored_bytes, self.stopped
        )
    }
}

/// Schemas, channels and chunks found so far.
#[derive(Default)]
struct Found {
    schemas: HashMap<u16, Arc<mcap::Schema<'static>>>,
    channels: HashMap<u16, mcap::records::Channel>,
    counts: BTreeMap<u16, u64>,
    chunks: Vec<ChunkIndex>,
    messages: u64,
    time_range: Option<(u64, u64)>,
}

/// Walks the file `file` of `file_len` bytes at `path` as the module doc says; errors only
/// when it does not start as an MCAP file.
pub(super) fn recover_index(
    path: &Path,
    file: &File,
    file_len: u64,
) -> Result<(Index, Recovery), BagError> {
    let magic = MAGIC.len() as u64;
    if file_len < magic || read_at(path, file, 0, MAGIC.len())? != MAGIC {
        return Err(BagError::Corrupt {
            path: path.to_path_buf(),
            offset: 0,
            reason: "no MCAP magic at the start".into(),
        });
    }
    let mut found = Found::default();
    let mut pos = magic;
    let stopped = loop {
        let left = file_len - pos;
        if left == 0 {
            break "the file ends after a complete record".to_string();
        }
        if left < 9 {
            break format!("record at byte {pos} cut off in its header");
        }
        let head = read_at(path, file, pos, 9)?;
        let (opcode, len) = (head[0], le_u64(&head[1..9]));
        if len > left - 9 {
            break format!(
                "record at byte {pos} cut off ({} bytes present, its length field says {len})",
                left - 9
            );
        }
        match opcode {
            op::DATA_END | op::FOOTER => break "end of the data section".to_string(),
            op::MESSAGE => break format!("message outside a chunk at byte {pos}"),
            op::CHUNK if len > MAX_CHUNK_BYTES => {
                break format!("chunk at byte {pos} larger than 4 GiB")
            }
            op::CHUNK => {
                let record = read_at(path, file, pos, 9 + len as usize)?;
                if let Err(reason) = found.chunk(&record, pos) {
                    break format!("chunk at byte {pos}: {reason}");
                }
            }
            op::SCHEMA | op::CHANNEL => {
                let body = read_at(path, file, pos + 9, len as usize)?;
                if let Err(reason) = claims_fit(opcode, &body) {
                    break format!("record at byte {pos}: {reason}");
                }
                match mcap::parse_record(opcode, &body) {
                    Ok(r) => found.definition(r.into_owned()),
                    Err(e) => break format!("record at byte {pos}: {e}"),
                }
            }
            _ => {}
        }
        pos += 9 + len;
    };
    let recovery = Recovery {
        messages: found.messages,
        chunks: found.chunks.len() as u64,
        readable_bytes: pos,
        ignored_bytes: file_len - pos,
        stopped,
    };
    Ok((found.into_index(path)?, recovery))
}

impl Found {
    /// Keeps a schema or channel record.
    fn definition(&mut self, record: Record<'static>) {
        match record {
            Record::Schema { header, data } => {
                let schema = mcap::Schema {
                    id: header.id,
                    name: header.name,
                    encoding: header.encoding,
                    data,
                };
                self.schemas.insert(schema.id, Arc::new(schema));
            }
            Record::Channel(channel) => {
                self.channels.insert(channel.id, channel);
            }
            _ => {}
        }
    }

    /// Takes the complete chunk record `record` (opcode and length included) found at byte
    /// `at`: its CRC is checked, its definitions kept, its messages counted. On an error
    /// nothing of the chunk is kept.
    fn chunk(&mut self, record: &[u8], at: u64) -> Result<(), String> {
        if !compression_name_fits(record) {
            return Err("compression name longer than the chunk".into());
        }
        let Record::Chunk { header, .. } =
            mcap::parse_record(op::CHUNK, &record[9..]).map_err(|e| e.to_string())?
        else {
            return Err("did not parse as a chunk".into());
        };
        chunk_sizes_fit(&header)?;
        let limit = (record.len() as u64).max(header.uncompressed_size) as usize;
        let times = header.message_start_time..=header.message_end_time;
        let mut definitions = Vec::new();
        let mut messages = Vec::new();
        for_each_record(record, limit, |r| match r {
            Record::Message { header, .. } => messages.push((header.channel_id, header.log_time)),
            r @ (Record::Schema { .. } | Record::Channel(_)) => definitions.push(r.into_owned()),
            _ => {}
        })
        .map_err(|e| e.to_string())?;
        if messages.iter().any(|(_, t)| !times.contains(t)) {
            return Err("message log time outside its chunk's range".into());
        }
        definitions.into_iter().for_each(|d| self.definition(d));
        for (channel, time) in messages {
            if !self.channels.contains_key(&channel) {
                return Err(format!("message on unknown channel {channel}"));
            }
            *self.counts.entry(channel).or_default() += 1;
            self.messages += 1;
            self.time_range = Some(match self.time_range {
                Some((first, last)) => (first.min(time), last.max(time)),
                None => (time, time),
            });
        }
        self.chunks.push(ChunkIndex {
            message_start_time: header.message_start_time,
            message_end_time: header.message_end_time,
            chunk_start_offset: at,
            chunk_length: record.len() as u64,
            message_index_offsets: BTreeMap::new(),
            message_index_length: 0,
            compression: header.compression,
            compressed_size: header.compressed_size,
            uncompressed_size: header.uncompressed_size,
        });
        Ok(())
    }

    /// The index of what was found.
    fn into_index(self, path: &Path) -> Result<Index, BagError> {
        let channels: HashMap<u16, Arc<mcap::Channel<'static>>> = self
            .channels
            .into_values()
            .map(|c| {
                let channel = mcap::Channel {
                    id: c.id,
                    topic: c.topic,
                    schema: self.schemas.get(&c.schema_id).cloned(),
                    message_encoding: c.message_encoding,
                    metadata: c.metadata,
                };
                (channel.id, Arc::new(channel))
            })
            .collect();
        Index::new(
            path,
            &channels,
            &self.counts,
            self.chunks,
            self.messages,
            self.time_range,
        )
    }
}
