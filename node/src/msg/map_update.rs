//! `stereosplat_msgs/msg/MapUpdate`: the global map on the wire, as increments (what changed
//! since the previous one) and snapshots (all of it). The definition is the `.msg` text
//! [`MAP_UPDATE_MSG`] (the file beside this one), from which the type hash is computed and
//! which the interop test hands to an independent CDR reader.
//!
//! The Gaussians ride in a `sensor_msgs/PointCloud2` in the world frame with FLOAT64
//! positions (see [`super::gaussians`]); their ids and source bins are parallel `uint64[]`
//! arrays rather than cloud channels, because PointCloud2 has no 64-bit integer type.

use super::cdr::{CdrReader, CdrWriter, DecodeError};
use super::sensor_msgs::PointCloud2;
use super::std_msgs::Header;
use super::{Message, MessageKind};

/// The definition of `stereosplat_msgs/msg/MapUpdate`.
pub const MAP_UPDATE_MSG: &str = include_str!("MapUpdate.msg");

/// One change of the global map (see the `.msg` text for the contract).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MapUpdate {
    /// Stamp of the bin that caused it; frame `world`.
    pub header: Header,
    /// Increments count 1, 2, 3, ...; a snapshot carries the sequence of the last increment
    /// it includes (0 before any).
    pub sequence: u64,
    /// True for a snapshot (the whole map), false for an increment.
    pub snapshot: bool,
    /// The last bin taken into the map.
    pub bin_id: u64,
    /// The id of each point of `gaussians`, in order.
    pub ids: Vec<u64>,
    /// The bin each point of `gaussians` came from, in order.
    pub source_bins: Vec<u64>,
    /// Ids that left the map (increments only).
    pub removed_ids: Vec<u64>,
    /// The added Gaussians (increment) or all of them (snapshot), world frame.
    pub gaussians: PointCloud2,
}

impl MapUpdate {
    /// Writes the message with its ids, source bins and cloud data drawn from `ids`,
    /// `source_bins` and `data` (a byte count and what appends them) instead of its own
    /// lists: a snapshot of a large map is encoded straight from the map, with no message
    /// beside the payload.
    pub fn write_streamed(
        &self,
        w: &mut CdrWriter,
        ids: impl ExactSizeIterator<Item = u64>,
        source_bins: impl ExactSizeIterator<Item = u64>,
        data: (usize, impl FnOnce(&mut Vec<u8>)),
    ) {
        self.header.write(w);
        w.u64(self.sequence);
        w.bool(self.snapshot);
        w.u64(self.bin_id);
        w.u64_seq_from(ids);
        w.u64_seq_from(source_bins);
        w.u64_seq(&self.removed_ids);
        self.gaussians.write_with_data(w, data.0, data.1);
    }
}

impl Message for MapUpdate {
    const KIND: MessageKind = MessageKind::MapUpdate;

    fn write(&self, w: &mut CdrWriter) {
        let data = &self.gaussians.data;
        self.write_streamed(
            w,
            self.ids.iter().copied(),
            self.source_bins.iter().copied(),
            (data.len(), |b: &mut Vec<u8>| b.extend_from_slice(data)),
        );
    }

    /// The cloud and the three id lists, with room for the header.
    fn size_hint(&self) -> usize {
        let ids = self.ids.len() + self.source_bins.len() + self.removed_ids.len();
        self.gaussians.size_hint() + 8 * ids + 256
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(r)?,
            sequence: r.u64("sequence")?,
            snapshot: r.bool("snapshot")?,
            bin_id: r.u64("bin_id")?,
            ids: r.u64_seq("ids")?,
            source_bins: r.u64_seq("source_bins")?,
            removed_ids: r.u64_seq("removed_ids")?,
            gaussians: PointCloud2::read(r)?,
        })
    }
}
