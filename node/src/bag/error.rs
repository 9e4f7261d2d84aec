//! The one error type of [`crate::bag`]: every variant that concerns a file names it.

use std::path::PathBuf;

/// Why a bag could not be written, opened or read, or a replay rate is unusable.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The operating system refused a file operation.
    #[error("{path}: {action}: {source}")]
    Io {
        /// The bag file.
        path: PathBuf,
        /// What was being done, e.g. "create" or "read chunk at byte 1234".
        action: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The MCAP library rejected a record (bad magic, truncated or malformed record, chunk CRC
    /// mismatch, undecodable compressed data, ...).
    #[error("{path}: {place}: {source}")]
    Format {
        /// The bag file.
        path: PathBuf,
        /// Which part of the file, e.g. "summary section" or "chunk at byte 1234".
        place: String,
        /// The library's error.
        source: mcap::McapError,
    },
    /// The file parses but contradicts itself (a CRC, an index or a count does not match).
    #[error("{path}: damaged at byte {offset}: {reason}")]
    Corrupt {
        /// The bag file.
        path: PathBuf,
        /// Byte offset of the damaged record.
        offset: u64,
        /// What does not match.
        reason: String,
    },
    /// The file has no summary, statistics or chunk index to read it by: usually a recording
    /// that was cut off before it was finished.
    #[error("{path}: {missing}; it is not a finished, chunked MCAP recording")]
    Unindexed {
        /// The bag file.
        path: PathBuf,
        /// What is missing.
        missing: String,
    },
    /// A channel this module cannot represent as a [`super::ChannelInfo`].
    #[error("{path}: channel {topic:?}: {reason}")]
    Channel {
        /// The bag file.
        path: PathBuf,
        /// The channel's topic.
        topic: String,
        /// Why it is unsupported.
        reason: String,
    },
    /// A replay speed factor that is not a finite number above zero.
    #[error("replay rate factor must be finite and greater than 0, got {0}")]
    BadRate(f64),
}
