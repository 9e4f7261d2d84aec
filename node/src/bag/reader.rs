//! [`BagReader`]: opens a finished MCAP file and streams its messages in log-time order.

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::records::{op, ChunkIndex, Record};

use super::records::{
    chunk_sizes_fit, compression_name_fits, for_each_record, le_u64, read_at, ChunkError,
    MAX_CHUNK_BYTES,
};
use super::recover::{recover_index, Recovery};
use super::summary::{read_index, ChannelSummary, Index};
use super::{BagError, Message};

/// An open bag: its summary is read and checked, messages are read on demand.
///
/// Needs a finished, chunked MCAP file with a summary (what [`super::BagWriter`], `ros2 bag
/// record` and most MCAP writers produce) whose channels have `ros2msg` schemas. Chunk and
/// summary CRCs are checked, so damage shows up as a [`BagError`], not as altered payloads.
pub struct BagReader {
    path: PathBuf,
    file: File,
    file_len: u64,
    index: Index,
}

impl BagReader {
    /// Opens `path` and reads its summary; fails on a truncated, unfinished or damaged file.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, BagError> {
        let (path, file, file_len) = open_file(path.as_ref())?;
        let index = read_index(&path, &file, file_len)?;
        Ok(Self {
            path,
            file,
            file_len,
            index,
        })
    }

    /// Opens a recording that may have been cut off (a recorder killed before it finished
    /// the file): its complete, CRC-checked chunks from the start up to the first cut-off or
    /// damaged record are read as a bag of their own, whatever the footer says. Says how
    /// much it kept. Errors only when the file cannot be read or does not start as MCAP.
    pub fn recover(path: impl AsRef<Path>) -> Result<(Self, Recovery), BagError> {
        let (path, file, file_len) = open_file(path.as_ref())?;
        let (index, recovery) = recover_index(&path, &file, file_len)?;
        let bag = Self {
            path,
            file,
            file_len,
            index,
        };
        Ok((bag, recovery))
    }

    /// [`BagReader::open`], or when the file is not a finished, intact recording,
    /// [`BagReader::recover`] with what it recovered. When both fail, the error of `open`.
    pub fn open_or_recover(path: impl AsRef<Path>) -> Result<(Self, Option<Recovery>), BagError> {
        let path = path.as_ref();
        match Self::open(path) {
            Ok(bag) => Ok((bag, None)),
            Err(strict) => match Self::recover(path) {
                Ok((bag, recovery)) => Ok((bag, Some(recovery))),
                Err(_) => Err(strict),
            },
        }
    }

    /// The bag's channels, in the order of their MCAP ids, with their message counts.
    pub fn channels(&self) -> &[ChannelSummary] {
        &self.index.channels
    }

    /// How many messages the bag holds.
    pub fn message_count(&self) -> u64 {
        self.index.message_count
    }

    /// The first and last log time in nanoseconds, `None` when the bag has no messages.
    pub fn time_range(&self) -> Option<(u64, u64)> {
        self.index.time_range
    }

    /// Iterates over all messages in log-time order (messages with equal log times in the order
    /// they were written). Memory stays bounded by the chunks that overlap in time, one chunk
    /// for a bag written in time order. After an error the iterator ends.
    pub fn messages(&self) -> Messages<'_> {
        Messages {
            bag: self,
            next_chunk: 0,
            pending: BinaryHeap::new(),
            yielded: 0,
            failed: false,
        }
    }

    /// A [`BagError::Corrupt`] at `offset` of this file.
    fn corrupt(&self, offset: u64, reason: String) -> BagError {
        BagError::Corrupt {
            path: self.path.clone(),
            offset,
            reason,
        }
    }

    /// Reads, checks and decodes the chunk that `chunk` indexes; calls `push` with each of its
    /// messages in file order.
    fn load_chunk(
        &self,
        chunk: &ChunkIndex,
        mut push: impl FnMut(Message),
    ) -> Result<(), BagError> {
        let at = chunk.chunk_start_offset;
        let within_file = at
            .checked_add(chunk.chunk_length)
            .is_some_and(|end| end <= self.file_len);
        if !within_file || chunk.chunk_length < 9 {
            return Err(self.corrupt(at, "chunk index points outside the file".into()));
        }
        if chunk.chunk_length > MAX_CHUNK_BYTES || chunk.uncompressed_size > MAX_CHUNK_BYTES {
            return Err(self.corrupt(at, "chunk larger than 4 GiB".into()));
        }
        let record = read_at(&self.path, &self.file, at, chunk.chunk_length as usize)?;
        if record[0] != op::CHUNK || le_u64(&record[1..9]) != chunk.chunk_length - 9 {
            return Err(self.corrupt(at, "chunk index does not point to a chunk".into()));
        }
        if !compression_name_fits(&record) {
            return Err(self.corrupt(
                at,
                "chunk's compression name is longer than the chunk".into(),
            ));
        }
        let format_error = |source| BagError::Format {
            path: self.path.clone(),
            place: format!("chunk at byte {at}"),
            source,
        };
        let Record::Chunk { header, .. } =
            mcap::parse_record(op::CHUNK, &record[9..]).map_err(format_error)?
        else {
            return Err(self.corrupt(at, "chunk record did not parse as a chunk".into()));
        };
        let agrees = header.message_start_time == chunk.message_start_time
            && header.message_end_time == chunk.message_end_time
            && header.uncompressed_size == chunk.uncompressed_size
            && header.compressed_size == chunk.compressed_size
            && header.compression == chunk.compression;
        if !agrees {
            return Err(self.corrupt(at, "chunk header disagrees with its index".into()));
        }
        chunk_sizes_fit(&header).map_err(|reason| self.corrupt(at, reason))?;
        let limit = chunk.chunk_length.max(chunk.uncompressed_size) as usize;
        let times = chunk.message_start_time..=chunk.message_end_time;
        let mut problem = None;
        for_each_record(&record, limit, |r| {
            let Record::Message { header, data } = r else {
                return;
            };
            let channel = self.index.by_id.get(&header.channel_id);
            match channel {
                _ if problem.is_some() => {}
                None => problem = Some(format!("message on unknown channel {}", header.channel_id)),
                Some(_) if !times.contains(&header.log_time) => {
                    problem = Some("message log time outside its chunk's range".into())
                }
                Some(channel) => push(Message {
                    channel: Arc::clone(channel),
                    log_time_ns: header.log_time,
                    publish_time_ns: header.publish_time,
                    sequence: header.sequence,
                    payload: data.into_owned(),
                }),
            }
        })
        .map_err(|e| match e {
            ChunkError::Format(source) => format_error(source),
            ChunkError::Claims(reason) => self.corrupt(at, reason),
        })?;
        match problem {
            Some(reason) => Err(self.corrupt(at, reason)),
            None => Ok(()),
        }
    }
}

/// Opens `path` for reading and learns its length.
fn open_file(path: &Path) -> Result<(PathBuf, File, u64), BagError> {
    let path = path.to_path_buf();
    let io_error = |action: &str, source| BagError::Io {
        path: path.clone(),
        action: action.into(),
        source,
    };
    let file = File::open(&path).map_err(|e| io_error("open", e))?;
    let file_len = file.metadata().map_err(|e| io_error("stat", e))?.len();
    Ok((path, file, file_len))
}

/// Iterator over a bag's messages in log-time order; see [`BagReader::messages`].
pub struct Messages<'a> {
    bag: &'a BagReader,
    /// The next chunk (in log-time visiting order) to load.
    next_chunk: usize,
    /// Loaded messages not yet yielded, earliest first.
    pending: BinaryHeap<Reverse<Pending>>,
    /// Messages yielded so far.
    yielded: u64,
    /// Set after an error: the iterator is over.
    failed: bool,
}

impl Messages<'_> {
    /// Whether the next unloaded chunk may hold a message due before everything pending.
    fn must_load(&self) -> bool {
        let Some(chunk) = self.bag.index.chunks.get(self.next_chunk) else {
            return false;
        };
        match self.pending.peek() {
            Some(Reverse(first)) => chunk.message_start_time <= first.message.log_time_ns,
            None => true,
        }
    }

    /// The next message, or `None` at the end, checking at the end that the count matches.
    fn advance(&mut self) -> Result<Option<Message>, BagError> {
        while self.must_load() {
            let chunk = &self.bag.index.chunks[self.next_chunk];
            self.next_chunk += 1;
            let pending = &mut self.pending;
            let mut in_chunk = 0;
            self.bag.load_chunk(chunk, |message| {
                pending.push(Reverse(Pending {
                    place: (chunk.chunk_start_offset, in_chunk),
                    message,
                }));
                in_chunk += 1;
            })?;
        }
        match self.pending.pop() {
            Some(Reverse(pending)) => {
                self.yielded += 1;
                Ok(Some(pending.message))
            }
            None if self.yielded == self.bag.index.message_count => Ok(None),
            None => Err(self.bag.corrupt(
                0,
                format!(
                    "statistics count {} messages, the chunks hold {}",
                    self.bag.index.message_count, self.yielded
                ),
            )),
        }
    }
}

impl Iterator for Messages<'_> {
    type Item = Result<Message, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let next = self.advance();
        self.failed = next.is_err();
        next.transpose()
    }
}

/// A loaded message, ordered by log time and then by its place in the file.
struct Pending {
    /// Byte offset of its chunk and its index in the chunk.
    place: (u64, u64),
    message: Message,
}

impl Pending {
    fn key(&self) -> (u64, (u64, u64)) {
        (self.message.log_time_ns, self.place)
    }
}

impl PartialEq for Pending {
    fn eq(&self, other: &Self) -> bool {
        self.key() == other.key()
    }
}

impl Eq for Pending {}

impl PartialOrd for Pending {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Pending {
    fn cmp(&self, other: &Self) -> Ordering {
        self.key().cmp(&other.key())
    }
}
