//! Why the tf buffer refused a transform or could not answer a lookup, with tf2's names
//! for the same cases where it has them.

use crate::msg::ConvertError;

/// Why a transform was not kept, or a lookup failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TfError {
    /// A frame name is empty (names the field).
    #[error("transform with an empty `{0}`")]
    EmptyFrameName(&'static str),
    /// Parent and child are the same frame.
    #[error("transform from frame `{0}` to itself")]
    SameFrame(String),
    /// A frame name longer than [`TfConfig::max_name_bytes`](super::TfConfig::max_name_bytes).
    #[error("frame name of {len} bytes (at most {max})")]
    NameTooLong {
        /// Its length.
        len: usize,
        /// The limit.
        max: usize,
    },
    /// Non-finite values or a quaternion that is not a rotation.
    #[error("transform {parent} -> {child}")]
    Invalid {
        /// The parent frame.
        parent: String,
        /// The child frame.
        child: String,
        /// What is wrong with its values.
        #[source]
        source: ConvertError,
    },
    /// A new frame while the buffer holds [`TfConfig::max_frames`](super::TfConfig::max_frames).
    #[error("frame `{frame}` refused: the buffer holds its {max} frames")]
    TooManyFrames {
        /// The refused name.
        frame: String,
        /// The limit.
        max: usize,
    },
    /// A sample older than the edge's newest minus the cache length.
    #[error("transform {parent} -> {child} at {stamp_ns} ns is older than the cache ({cache_ns} ns behind the newest, {newest_ns} ns)")]
    TooOld {
        /// The parent frame.
        parent: String,
        /// The child frame.
        child: String,
        /// Its stamp.
        stamp_ns: i64,
        /// The edge's newest stamp.
        newest_ns: i64,
        /// The cache length.
        cache_ns: i64,
    },
    /// A sample at a stamp the edge already holds.
    #[error("transform {parent} -> {child} at {stamp_ns} ns repeats a held stamp")]
    Repeated {
        /// The parent frame.
        parent: String,
        /// The child frame.
        child: String,
        /// The stamp.
        stamp_ns: i64,
    },
    /// A transform that would make a frame its own ancestor (or a walk that met one).
    #[error("transform {parent} -> {child} would close a loop in the tf tree")]
    Loop {
        /// The parent frame.
        parent: String,
        /// The child frame.
        child: String,
    },
    /// A dynamic transform from a new parent, older than the current parent's newest sample.
    #[error("transform {parent} -> {child} at {stamp_ns} ns is older than the newest ({newest_ns} ns) from its current parent `{current_parent}`")]
    StaleParent {
        /// The new parent.
        parent: String,
        /// The child frame.
        child: String,
        /// The parent the child has.
        current_parent: String,
        /// The transform's stamp.
        stamp_ns: i64,
        /// The current edge's newest stamp.
        newest_ns: i64,
    },
    /// A frame no transform has named.
    #[error("frame `{0}` does not exist")]
    UnknownFrame(String),
    /// The two frames are in different trees.
    #[error("frames `{target_frame}` and `{source_frame}` are not connected (different trees)")]
    NotConnected {
        /// The lookup's target.
        target_frame: String,
        /// The lookup's source.
        source_frame: String,
    },
    /// A stamp before an edge's oldest sample.
    #[error("lookup at {stamp_ns} ns would extrapolate into the past: edge {parent} -> {child} starts at {oldest_ns} ns")]
    ExtrapolationPast {
        /// The edge's parent.
        parent: String,
        /// The edge's child.
        child: String,
        /// The stamp asked for.
        stamp_ns: i64,
        /// The edge's oldest stamp.
        oldest_ns: i64,
    },
    /// A stamp after an edge's newest sample.
    #[error("lookup at {stamp_ns} ns would extrapolate into the future: edge {parent} -> {child} ends at {newest_ns} ns")]
    ExtrapolationFuture {
        /// The edge's parent.
        parent: String,
        /// The edge's child.
        child: String,
        /// The stamp asked for.
        stamp_ns: i64,
        /// The edge's newest stamp.
        newest_ns: i64,
    },
    /// [`TfBuffer::lookup_static`](super::TfBuffer::lookup_static) met a dynamic edge.
    #[error("edge {parent} -> {child} is dynamic, not a static mount")]
    NotStatic {
        /// The edge's parent.
        parent: String,
        /// The edge's child.
        child: String,
    },
}
