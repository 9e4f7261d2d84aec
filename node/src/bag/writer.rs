//! [`BagWriter`]: appends messages to a new MCAP file with the ROS 2 profile.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::MessageHeader;
use mcap::{Compression, WriteOptions, Writer};

use super::{BagError, ChannelInfo, PROFILE, SCHEMA_ENCODING};

/// The channel metadata key under which the ros2 profile stores the publishers' QoS.
pub(super) const QOS_KEY: &str = "offered_qos_profiles";

/// Writes messages to an MCAP file: zstd-compressed chunks of about 1 MiB, chunk and summary
/// CRCs, message and chunk indexes and statistics (what `ros2 bag`, Foxglove and
/// [`super::BagReader`] expect). Schemas and channels are registered on first use.
///
/// Call [`BagWriter::finish`] to learn whether the end of the file was written; a writer that
/// is dropped instead still writes the summary, but errors are lost.
pub struct BagWriter {
    path: PathBuf,
    mcap: Writer<BufWriter<File>>,
    channel_ids: HashMap<ChannelInfo, u16>,
}

impl BagWriter {
    /// Creates (or truncates) the file at `path` and writes the MCAP header.
    pub fn create(path: impl AsRef<Path>) -> Result<Self, BagError> {
        let path = path.as_ref().to_path_buf();
        let file = File::create(&path).map_err(|source| BagError::Io {
            path: path.clone(),
            action: "create".into(),
            source,
        })?;
        let options = WriteOptions::new()
            .profile(PROFILE)
            .library(concat!("stereosplat ", env!("CARGO_PKG_VERSION")))
            .compression(Some(Compression::Zstd));
        let mcap = options
            .create(BufWriter::new(file))
            .map_err(|source| format_error(&path, source))?;
        Ok(Self {
            path,
            mcap,
            channel_ids: HashMap::new(),
        })
    }

    /// Appends one message on `channel`. Log times need not increase (readers sort by them);
    /// `payload` is stored as is, and may be empty.
    pub fn write(
        &mut self,
        channel: &ChannelInfo,
        log_time_ns: u64,
        publish_time_ns: u64,
        sequence: u32,
        payload: &[u8],
    ) -> Result<(), BagError> {
        let channel_id = self.channel_id(channel)?;
        let header = MessageHeader {
            channel_id,
            sequence,
            log_time: log_time_ns,
            publish_time: publish_time_ns,
        };
        self.mcap
            .write_to_known_channel(&header, payload)
            .map_err(|source| format_error(&self.path, source))
    }

    /// Closes the chunk being written and hands the bytes so far to the operating system, so
    /// a process killed afterwards leaves every message written up to here in a complete
    /// chunk that [`super::BagReader::recover`] reads.
    pub fn flush(&mut self) -> Result<(), BagError> {
        self.mcap
            .flush()
            .map_err(|source| format_error(&self.path, source))
    }

    /// Writes the last chunk, the summary and the footer, and flushes the file to disk.
    pub fn finish(self) -> Result<(), BagError> {
        let Self { path, mut mcap, .. } = self;
        mcap.finish()
            .map_err(|source| format_error(&path, source))?;
        let io_error = |action: &str, source| BagError::Io {
            path: path.clone(),
            action: action.into(),
            source,
        };
        let file = mcap
            .into_inner()
            .into_inner()
            .map_err(|e| io_error("flush", e.into_error()))?;
        file.sync_all().map_err(|e| io_error("sync", e))
    }

    /// The id of `channel`, registering its schema and the channel on first use.
    fn channel_id(&mut self, channel: &ChannelInfo) -> Result<u16, BagError> {
        if let Some(&id) = self.channel_ids.get(channel) {
            return Ok(id);
        }
        let schema_id = self
            .mcap
            .add_schema(
                &channel.schema_name,
                SCHEMA_ENCODING,
                channel.schema_text.as_bytes(),
            )
            .map_err(|source| format_error(&self.path, source))?;
        // The ros2 profile requires this key; empty means "publisher's QoS unknown", and
        // rosbag2 then replays with its default QoS.
        let metadata = BTreeMap::from([(QOS_KEY.to_string(), channel.offered_qos.clone())]);
        let id = self
            .mcap
            .add_channel(
                schema_id,
                &channel.topic,
                &channel.message_encoding,
                &metadata,
            )
            .map_err(|source| format_error(&self.path, source))?;
        self.channel_ids.insert(channel.clone(), id);
        Ok(id)
    }
}

/// A library error while writing `path`.
fn format_error(path: &Path, source: mcap::McapError) -> BagError {
    BagError::Format {
        path: path.to_path_buf(),
        place: "write".into(),
        source,
    }
}
