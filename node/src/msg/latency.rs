//! The node's own messages, package `stereosplat_msgs`: per-bin latency
//! ([`BinLatency`]) and counters ([`Diagnostics`] of [`Counter`]s).
//!
//! Their definitions are the `.msg` texts [`BIN_LATENCY_MSG`], [`COUNTER_MSG`] and
//! [`DIAGNOSTICS_MSG`] (files beside this one): the type hashes are computed from them and
//! the interop test registers the same texts with an independent CDR reader, so the wire
//! layout has one definition.
//!
//! `stereosplat_msgs/msg/BinLatency`, in wire order:
//! `uint64 bin_id`, `int64 first_frame_arrival_ns`, `int64 bin_close_ns`,
//! `int64 model_start_ns`, `int64 model_end_ns`, `int64 render_end_ns`, `int64 publish_ns`,
//! `uint32 queue_depth`, `uint64 drops`, `uint64 bad_messages`, `uint8 check_verdict`,
//! `uint8 check_action`, `uint8 fallback_verdict`, `uint32 check_samples`,
//! `float64 check_score`, `float64 fallback_score`, and from version 2 on the progressive
//! pass's stage stamps `int64 base_end_ns`, `int64 pseudo_render_end_ns`,
//! `int64 enhance_end_ns`, `int64 plus_end_ns`, `int64 fuse_end_ns`, from version 3 on
//! `string operating_point`, and from version 4 on `int64 map_fused_ns`. Each version only
//! appends, so an older payload (an older recording) is a newer one cut short: the reader
//! takes a payload that ends right after `fallback_score` as version 1 (stage stamps 0, no
//! point), one that ends right after `fuse_end_ns` as version 2 (no point) and one that ends
//! right after `operating_point` as version 3 (`map_fused_ns` 0); one that ends inside the
//! appended fields is a truncation error.
//!
//! `stereosplat_msgs/msg/Diagnostics`: `int64 stamp_ns`, `Counter[] counters`, where
//! `stereosplat_msgs/msg/Counter` is `string kind`, `uint64 count`.

use super::cdr::{CdrReader, CdrWriter, DecodeError};
use super::{Message, MessageKind};

/// The definition of `stereosplat_msgs/msg/BinLatency`.
pub const BIN_LATENCY_MSG: &str = include_str!("BinLatency.msg");
/// The definition of `stereosplat_msgs/msg/Counter`.
pub const COUNTER_MSG: &str = include_str!("Counter.msg");
/// The definition of `stereosplat_msgs/msg/Diagnostics`.
pub const DIAGNOSTICS_MSG: &str = include_str!("Diagnostics.msg");

/// How long one bin took through the node. Stamps are nanoseconds since the Unix epoch on
/// the node's clock, 0 where the bin never reached the stage; differences give the stage
/// latencies. It also carries the bin's self-check (`model::consistency`) and what the node
/// did when it failed (`node::pipeline::self_check`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BinLatency {
    /// The bin's number, counted from 0 since the node started.
    pub bin_id: u64,
    /// When the bin's first stereo frame arrived.
    pub first_frame_arrival_ns: i64,
    /// When the bin closed (its last frame arrived).
    pub bin_close_ns: i64,
    /// When the worker started the model on it.
    pub model_start_ns: i64,
    /// When the model finished.
    pub model_end_ns: i64,
    /// When the renders of the bin's map finished.
    pub render_end_ns: i64,
    /// When the bin's map was published.
    pub publish_ns: i64,
    /// Bins waiting in the worker queue when this one was taken.
    pub queue_depth: u32,
    /// Bins dropped by the queue's policy since the node started.
    pub drops: u64,
    /// Malformed input messages counted since the node started.
    pub bad_messages: u64,
    /// The self-check of the bin's map: 0 not run (no map), 1 pass, 2 fail, 3 undetermined.
    pub check_verdict: u8,
    /// What was done about a failed check: 0 nothing, 1 flagged, 2 opacity lowered, 3
    /// replaced by SGM's map.
    pub check_action: u8,
    /// The check of SGM's map when `check_action` is 3 (codes as `check_verdict`), else 0.
    pub fallback_verdict: u8,
    /// Textured samples the check scored.
    pub check_samples: u32,
    /// Fraction of the samples whose left and right patches agree, in [0, 1].
    pub check_score: f64,
    /// The same for SGM's map when `check_action` is 3, else 0.
    pub fallback_score: f64,
    /// The progressive pass's stages, splitting `model_start_ns..model_end_ns` (0 without
    /// the pass, and in version-1 payloads): G_base done.
    pub base_end_ns: i64,
    /// Pseudo views rendered.
    pub pseudo_render_end_ns: i64,
    /// Pseudo views enhanced (equal to `pseudo_render_end_ns` with the enhancer off).
    pub enhance_end_ns: i64,
    /// Pseudo pairs through the network (G_plus).
    pub plus_end_ns: i64,
    /// G_base and G_plus fused (the self-check follows, up to `model_end_ns`).
    pub fuse_end_ns: i64,
    /// The operating point the map was made with (empty in version-1 and 2 payloads).
    pub operating_point: String,
    /// When the bin's map was fused into the global map and its change journaled (tiles
    /// paged in and out with it included); publishing the bin's messages follows, up to
    /// `publish_ns`. 0 in older payloads.
    pub map_fused_ns: i64,
}

impl BinLatency {
    /// The stage stamps version 2 appended, in wire order.
    fn stage_stamps(&self) -> [i64; 5] {
        [
            self.base_end_ns,
            self.pseudo_render_end_ns,
            self.enhance_end_ns,
            self.plus_end_ns,
            self.fuse_end_ns,
        ]
    }
}

impl Message for BinLatency {
    const KIND: MessageKind = MessageKind::BinLatency;

    fn write(&self, w: &mut CdrWriter) {
        w.u64(self.bin_id);
        for t in [
            self.first_frame_arrival_ns,
            self.bin_close_ns,
            self.model_start_ns,
            self.model_end_ns,
            self.render_end_ns,
            self.publish_ns,
        ] {
            w.i64(t);
        }
        w.u32(self.queue_depth);
        w.u64(self.drops);
        w.u64(self.bad_messages);
        w.u8(self.check_verdict);
        w.u8(self.check_action);
        w.u8(self.fallback_verdict);
        w.u32(self.check_samples);
        w.f64(self.check_score);
        w.f64(self.fallback_score);
        for t in self.stage_stamps() {
            w.i64(t);
        }
        w.string(&self.operating_point);
        w.i64(self.map_fused_ns);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let mut l = Self {
            bin_id: r.u64("bin_id")?,
            first_frame_arrival_ns: r.i64("first_frame_arrival_ns")?,
            bin_close_ns: r.i64("bin_close_ns")?,
            model_start_ns: r.i64("model_start_ns")?,
            model_end_ns: r.i64("model_end_ns")?,
            render_end_ns: r.i64("render_end_ns")?,
            publish_ns: r.i64("publish_ns")?,
            queue_depth: r.u32("queue_depth")?,
            drops: r.u64("drops")?,
            bad_messages: r.u64("bad_messages")?,
            check_verdict: r.u8("check_verdict")?,
            check_action: r.u8("check_action")?,
            fallback_verdict: r.u8("fallback_verdict")?,
            check_samples: r.u32("check_samples")?,
            check_score: r.f64("check_score")?,
            fallback_score: r.f64("fallback_score")?,
            ..Self::default()
        };
        // Version 1 ends here (no padding follows a final, 8-aligned f64); a payload with
        // part of version 2's stamps is truncated, and reading them says so.
        if r.remaining() > 0 {
            l.base_end_ns = r.i64("base_end_ns")?;
            l.pseudo_render_end_ns = r.i64("pseudo_render_end_ns")?;
            l.enhance_end_ns = r.i64("enhance_end_ns")?;
            l.plus_end_ns = r.i64("plus_end_ns")?;
            l.fuse_end_ns = r.i64("fuse_end_ns")?;
        }
        if r.remaining() > 0 {
            l.operating_point = r.string("operating_point")?;
        }
        // A version-3 payload ends after the string, before any padding to the stamp.
        if r.remaining() > 0 {
            l.map_fused_ns = r.i64("map_fused_ns")?;
        }
        Ok(l)
    }
}

/// One named counter.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Counter {
    /// What is counted (e.g. `bad_message/left_image`, `drop/worker_queue`).
    pub kind: String,
    /// How many since the node started.
    pub count: u64,
}

/// Fewest bytes one `Counter` takes on the wire: an empty string (length and NUL) and the
/// count.
const COUNTER_MIN_BYTES: usize = 4 + 1 + 8;

impl Message for Counter {
    const KIND: MessageKind = MessageKind::Counter;

    fn write(&self, w: &mut CdrWriter) {
        w.string(&self.kind);
        w.u64(self.count);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            kind: r.string("counters.kind")?,
            count: r.u64("counters.count")?,
        })
    }
}

/// The node's counters at one moment.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Diagnostics {
    /// When the counters were read, nanoseconds since the Unix epoch.
    pub stamp_ns: i64,
    /// The counters, in the node's order.
    pub counters: Vec<Counter>,
}

impl Message for Diagnostics {
    const KIND: MessageKind = MessageKind::Diagnostics;

    fn write(&self, w: &mut CdrWriter) {
        w.i64(self.stamp_ns);
        w.seq_len(self.counters.len());
        for c in &self.counters {
            c.write(w);
        }
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let stamp_ns = r.i64("stamp_ns")?;
        let n = r.seq_len("counters", COUNTER_MIN_BYTES)?;
        let counters = (0..n).map(|_| Counter::read(r)).collect::<Result<_, _>>()?;
        Ok(Self { stamp_ns, counters })
    }
}
