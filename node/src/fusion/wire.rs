//! Increments and snapshots as `stereosplat_msgs/MapUpdate` messages and back, positions in
//! f64 end to end so a subscriber's replica is as exact as the node's map.

use glam::DVec3;

use super::{GaussianId, GlobalMap, Increment, Snapshot, WorldGaussian};
use crate::msg::cdr::CdrWriter;
use crate::msg::gaussians::{
    cloud_from_records, cloud_layout, gaussian, put_record, record, records_from_cloud, Record,
};
use crate::msg::map_update::MapUpdate;
use crate::msg::std_msgs::Header;
use crate::msg::ConvertError;

/// What a decoded [`MapUpdate`] holds.
#[derive(Clone, Debug, PartialEq)]
pub enum Update {
    /// Apply it to the replica (`MapReplica::apply`).
    Increment(Increment),
    /// Replace the replica with it (`MapReplica::from_snapshot`).
    Snapshot(Snapshot),
}

/// Why a MapUpdate's parts do not fit together.
#[derive(Debug, thiserror::Error)]
pub enum WireError {
    /// The Gaussian cloud does not decode.
    #[error("map update: {0}")]
    Cloud(#[from] ConvertError),
    /// `ids`, `source_bins` and the cloud disagree in length.
    #[error("map update: {ids} ids, {bins} source bins, {points} points")]
    Lengths {
        /// Ids given.
        ids: usize,
        /// Source bins given.
        bins: usize,
        /// Points in the cloud.
        points: usize,
    },
    /// A snapshot that lists removed ids.
    #[error("map update: a snapshot with {0} removed ids")]
    SnapshotRemoves(usize),
}

/// The increment as message number `sequence`.
pub fn increment_message(
    inc: &Increment,
    sequence: u64,
    header: Header,
) -> Result<MapUpdate, ConvertError> {
    let mut msg = message(inc.added.iter().map(|(id, g)| (*id, g)), header)?;
    msg.sequence = sequence;
    msg.bin_id = inc.bin_id;
    msg.removed_ids = inc.removed.iter().map(|id| id.0).collect();
    Ok(msg)
}

/// The snapshot, which includes increments up to `sequence`.
pub fn snapshot_message(
    snap: &Snapshot,
    sequence: u64,
    header: Header,
) -> Result<MapUpdate, ConvertError> {
    let gaussians = snap.gaussians.iter().map(|(id, g)| (*id, g));
    Ok(as_snapshot(
        message(gaussians, header)?,
        snap.last_bin_id,
        sequence,
    ))
}

/// The whole map in memory as an encoded snapshot message numbered by its increments: the
/// bytes of [`snapshot_message`] of [`GlobalMap::snapshot`], written straight from the map
/// with no message or copy of the map beside them, since the periodic snapshot of a large
/// map is the node's largest message.
pub fn encode_map_snapshot(map: &GlobalMap, header: Header) -> Result<Vec<u8>, ConvertError> {
    let cloud = cloud_layout(map.len(), header.clone(), true)?;
    let bytes = cloud.row_step as usize;
    let head = as_snapshot(
        MapUpdate {
            header,
            gaussians: cloud,
            ..MapUpdate::default()
        },
        map.last_bin_id,
        map.increments(),
    );
    let mut w = CdrWriter::with_capacity(bytes + 16 * map.len() + 1024);
    let gaussians = map.gaussians.iter();
    head.write_streamed(
        &mut w,
        gaussians.clone().map(|(id, _)| id.0),
        gaussians.clone().map(|(_, g)| g.bin_id),
        (bytes, |data: &mut Vec<u8>| {
            for (_, g) in gaussians {
                put_record(data, &world_record(g), true);
            }
        }),
    );
    Ok(w.into_bytes())
}

/// `msg` marked as the snapshot after `last_bin_id`, numbered `sequence`.
fn as_snapshot(mut msg: MapUpdate, last_bin_id: Option<u64>, sequence: u64) -> MapUpdate {
    msg.sequence = sequence;
    msg.snapshot = true;
    msg.bin_id = last_bin_id.unwrap_or(0);
    msg
}

/// The message of `gaussians` (in id order), each taken into it one by one.
fn message<'a>(
    gaussians: impl ExactSizeIterator<Item = (GaussianId, &'a WorldGaussian)> + Clone,
    header: Header,
) -> Result<MapUpdate, ConvertError> {
    let records = gaussians.clone().map(|(_, g)| world_record(g));
    Ok(MapUpdate {
        gaussians: cloud_from_records(records, header.clone(), true)?,
        header,
        ids: gaussians.clone().map(|(id, _)| id.0).collect(),
        source_bins: gaussians.map(|(_, g)| g.bin_id).collect(),
        ..MapUpdate::default()
    })
}

/// The cloud record of a world Gaussian (its position in f64).
fn world_record(g: &WorldGaussian) -> Record {
    let rest = renderer::Gaussian {
        mean: glam::Vec3::ZERO,
        log_scale: g.log_scale,
        rotation: g.rotation,
        opacity: g.opacity,
        color: g.color,
        confidence: g.confidence,
    };
    record(g.position, &rest)
}

/// The increment or snapshot a message holds. A snapshot without bins taken
/// (`bin_id` 0 and no Gaussians) has `last_bin_id` 0 too: the message cannot tell them
/// apart, and a replica only needs the Gaussians.
pub fn decode_update(msg: &MapUpdate) -> Result<Update, WireError> {
    let records = records_from_cloud(&msg.gaussians)?;
    if records.len() != msg.ids.len() || records.len() != msg.source_bins.len() {
        return Err(WireError::Lengths {
            ids: msg.ids.len(),
            bins: msg.source_bins.len(),
            points: records.len(),
        });
    }
    let gaussians: Vec<(GaussianId, WorldGaussian)> = records
        .iter()
        .zip(msg.ids.iter().zip(&msg.source_bins))
        .map(|(r, (&id, &bin_id))| {
            let g = gaussian(r, DVec3::ZERO);
            let world = WorldGaussian {
                position: DVec3::new(r[0], r[1], r[2]),
                log_scale: g.log_scale,
                rotation: g.rotation,
                opacity: g.opacity,
                color: g.color,
                confidence: g.confidence,
                bin_id,
            };
            (GaussianId(id), world)
        })
        .collect();
    if msg.snapshot {
        if !msg.removed_ids.is_empty() {
            return Err(WireError::SnapshotRemoves(msg.removed_ids.len()));
        }
        return Ok(Update::Snapshot(Snapshot {
            last_bin_id: Some(msg.bin_id),
            gaussians,
        }));
    }
    Ok(Update::Increment(Increment {
        bin_id: msg.bin_id,
        added: gaussians,
        removed: msg.removed_ids.iter().map(|&id| GaussianId(id)).collect(),
        stats: Default::default(),
    }))
}
