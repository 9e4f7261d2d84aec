//! What the map publishes: per-bin increments (what changed), full snapshots, and the
//! replica a subscriber keeps by applying them in order.

use std::collections::{BTreeMap, BTreeSet};

use super::{GaussianId, WorldGaussian};

/// How one bin's Gaussians fared, for diagnostics topics and logs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InsertStats {
    /// Gaussians in the bin's set.
    pub input: usize,
    /// Gaussians skipped for a NaN or infinite field.
    pub skipped_invalid: usize,
    /// Gaussians skipped for an opacity below the floor.
    pub pruned_opacity: usize,
    /// Gaussians kept out of the map by the keep rule ([`super::Keep`]): farther from
    /// their bin's camera than the range, or less confident than the floor.
    pub not_kept: usize,
    /// Gaussians dropped because their cell already held Gaussians of equal or higher
    /// confidence.
    pub dropped_lower_confidence: usize,
    /// Gaussians of earlier bins removed because this bin beat them in their cell.
    pub replaced: usize,
    /// Gaussians removed to keep the map within its budget (earlier ones and this bin's).
    pub evicted: usize,
}

/// What one call to `GlobalMap::insert_bin` changed. `added` and `removed` are net: an id
/// is in at most one of them, `removed` names only ids published before, and `added` only
/// ids still in the map after the call. Both are sorted by id.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Increment {
    /// The bin that produced this change.
    pub bin_id: u64,
    /// New Gaussians with their ids.
    pub added: Vec<(GaussianId, WorldGaussian)>,
    /// Ids of Gaussians that left the map (replaced or evicted).
    pub removed: Vec<GaussianId>,
    /// Counts of what happened to the bin's Gaussians.
    pub stats: InsertStats,
}

impl Increment {
    /// True when the map did not change.
    pub fn is_empty(&self) -> bool {
        self.added.is_empty() && self.removed.is_empty()
    }
}

/// The whole map at one moment: every Gaussian with its id, sorted by id, and the last bin
/// taken in (`None` before the first).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// The last bin inserted.
    pub last_bin_id: Option<u64>,
    /// All Gaussians, sorted by id.
    pub gaussians: Vec<(GaussianId, WorldGaussian)>,
}

impl Snapshot {
    /// The snapshot of an id-ordered store's entries.
    pub(super) fn of<'a>(
        gaussians: impl Iterator<Item = (&'a GaussianId, &'a WorldGaussian)>,
        last_bin_id: Option<u64>,
    ) -> Self {
        Self {
            last_bin_id,
            gaussians: gaussians.map(|(&id, g)| (id, *g)).collect(),
        }
    }
}

/// An increment that does not fit the replica it is applied to (a missed or repeated
/// message): the replica is unchanged and should be reset from a snapshot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplicaError {
    /// The increment removes an id the replica does not hold.
    #[error("increment of bin {bin_id} removes Gaussian {id} which the replica does not hold")]
    UnknownId {
        /// The increment's bin.
        bin_id: u64,
        /// The missing id.
        id: u64,
    },
    /// The increment adds an id the replica already holds.
    #[error("increment of bin {bin_id} adds Gaussian {id} which the replica already holds")]
    DuplicateId {
        /// The increment's bin.
        bin_id: u64,
        /// The repeated id.
        id: u64,
    },
}

/// A copy of the global map rebuilt from what was published: start empty or from a
/// snapshot, then apply increments in order. What a subscriber (and the tests) keep.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MapReplica {
    gaussians: BTreeMap<GaussianId, WorldGaussian>,
    last_bin_id: Option<u64>,
}

impl MapReplica {
    /// An empty replica (the state before the first increment).
    pub fn new() -> Self {
        Self::default()
    }

    /// A replica holding exactly `snapshot`.
    pub fn from_snapshot(snapshot: &Snapshot) -> Self {
        Self {
            gaussians: snapshot.gaussians.iter().copied().collect(),
            last_bin_id: snapshot.last_bin_id,
        }
    }

    /// Applies one increment: removals, then additions. On error nothing changes.
    pub fn apply(&mut self, inc: &Increment) -> Result<(), ReplicaError> {
        let bin_id = inc.bin_id;
        if let Some(id) = inc
            .removed
            .iter()
            .find(|id| !self.gaussians.contains_key(id))
        {
            return Err(ReplicaError::UnknownId { bin_id, id: id.0 });
        }
        let removed: BTreeSet<_> = inc.removed.iter().collect();
        if let Some((id, _)) = inc
            .added
            .iter()
            .find(|(id, _)| self.gaussians.contains_key(id) && !removed.contains(id))
        {
            return Err(ReplicaError::DuplicateId { bin_id, id: id.0 });
        }
        for id in &inc.removed {
            self.gaussians.remove(id);
        }
        self.gaussians.extend(inc.added.iter().copied());
        self.last_bin_id = Some(bin_id);
        Ok(())
    }

    /// Number of Gaussians held.
    pub fn len(&self) -> usize {
        self.gaussians.len()
    }

    /// True when no Gaussian is held.
    pub fn is_empty(&self) -> bool {
        self.gaussians.is_empty()
    }

    /// The Gaussians in id order (for export and bird's-eye views).
    pub fn gaussians(&self) -> impl Iterator<Item = (GaussianId, &WorldGaussian)> {
        self.gaussians.iter().map(|(&id, g)| (id, g))
    }

    /// Everything held, as a snapshot.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot::of(self.gaussians.iter(), self.last_bin_id)
    }
}
