//! The fused global Gaussian map: bin maps (f32, bin-local) in, one world map (f64
//! positions) out, published as increments plus snapshots.
//!
//! Fusion rule (per cell). World space is hashed into cubes of `cell_size` metres. A new
//! bin's valid Gaussians are grouped by cell. For each cell they touch:
//! - an empty cell takes all of them;
//! - an occupied cell is taken over when the bin's highest confidence in that cell is
//!   strictly higher than the cell's current highest confidence: every Gaussian already in
//!   the cell is removed and the bin's Gaussians of that cell are added;
//! - otherwise (equal or lower) the bin's Gaussians of that cell are dropped.
//!
//! So every cell holds the Gaussians of exactly one bin. Opacity and confidence are clamped
//! to [0, 1] on the way in, here and in every reader of a stored map (a confidence of 1e30
//! would otherwise win its cells for ever). Gaussians with a NaN or infinite
//! field, with an opacity below `opacity_floor`, or outside the keep rule ([`Keep`]: farther
//! than `keep.max_range_m` from their bin's camera, or less confident than
//! `keep.min_confidence`) are skipped before the rule (and counted). The keep rule exists for
//! the map's consumers: a bin map's far Gaussians (sky placed at the network's farthest depth,
//! distant matches with little support) render the bin's own views well but, fused into the
//! world, float above the road that later bins see from close by.
//!
//! Budget: after a bin is fused, while the map holds more than `max_gaussians` in memory,
//! whole cells are evicted: ground column by ground column (x-y squares of about 16 m), the
//! farthest (column centre) from the latest bin's origin first, and within a column the
//! farthest cell (centre) first, ties by key. A map kept on disk pages far tiles out
//! instead (`tiles`, `crate::store::map_store`), so its budget bounds what is in memory
//! and eviction is only the last resort. Ids are u64, assigned in increasing order in the
//! bin's input order, never reused.

mod cells;
mod export;
mod increments;
mod journal;
mod journal_writer;
mod snapshot;
mod tiles;
mod wire;

use std::collections::BTreeMap;

use imbl::OrdMap;
use rustc_hash::FxHashMap as HashMap;

use glam::{DAffine3, DMat3, DQuat, DVec2, DVec3, Quat, Vec3};
use renderer::gaussians::LengthMismatch;
use renderer::GaussianSet;

pub use cells::{cell_centre, cell_of, CellKey};
pub use export::{bev_image, local_set, save_bev_png, BevView, ExportError};
pub use increments::{Increment, InsertStats, MapReplica, ReplicaError, Snapshot};
pub use journal::{
    segment_path, segments, AtTornTail, FailedWrite, Replay, TornTail,
    HEADER_BYTES as JOURNAL_HEADER_BYTES,
};
pub use journal_writer::{
    create_dir_durably, open_on_disk, JournalWriter, OpenSegment, SegmentFile,
};
pub use snapshot::StoreError;
pub use tiles::{
    collect_garbage, read_tile, tile_distance, tile_path, write_tile, PageEvent, PagedTile, TileKey,
};
pub use wire::{
    decode_update, encode_map_snapshot, increment_message, snapshot_message, Update, WireError,
};

use cells::{eviction_order, CellIndex};

/// A Gaussian's id in the global map: unique for the map's life, never reused, so
/// subscribers can key their copies on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct GaussianId(pub u64);

/// One Gaussian in the world frame. The centre is f64 so the map stays exact (far below a
/// millimetre) kilometres from the world origin; the rest keeps the renderer's f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldGaussian {
    /// Centre, world frame, metres.
    pub position: DVec3,
    /// Natural log of the standard deviations along the rotated axes (rigid transforms keep
    /// them).
    pub log_scale: Vec3,
    /// Orientation in the world frame (unit; the bin's rotation composed with the pose's).
    pub rotation: Quat,
    /// Opacity in [0, 1].
    pub opacity: f32,
    /// Linear RGB colour.
    pub color: Vec3,
    /// The producer's confidence, [0, 1]; the fusion rule compares it.
    pub confidence: f32,
    /// The bin this Gaussian came from.
    pub bin_id: u64,
}

impl WorldGaussian {
    /// Whether every field is finite (NaN and infinities are not).
    pub fn is_finite(&self) -> bool {
        self.position.is_finite()
            && self.log_scale.is_finite()
            && self.rotation.is_finite()
            && self.opacity.is_finite()
            && self.color.is_finite()
            && self.confidence.is_finite()
    }
}

/// Which of a bin map's Gaussians the global map takes in (the rest stay in the bin map,
/// published with it, but are not fused).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keep {
    /// Gaussians farther than this from their bin's camera (the bin frame's origin), metres,
    /// are not fused: sky and far, weakly supported depth. Infinity keeps every distance.
    pub max_range_m: f32,
    /// Gaussians less confident than this are not fused (0 keeps all).
    pub min_confidence: f32,
}

impl Default for Keep {
    /// Within 20 m of the bin's camera, any confidence: chosen on the held-out drive of
    /// `results/fused_map/` (`stereosplat research eval-map --sky-ranges`), where it clears the
    /// sky over the road in the bird's-eye view and, with each bin's far part drawn behind the
    /// map as its sky layer ([`Keep::backdrop`]), gives the best fused-map scores with the
    /// fewest Gaussians of every keep range tried (20, 30, 40 m, everything).
    fn default() -> Self {
        Self {
            max_range_m: DEFAULT_MAX_RANGE_M,
            min_confidence: 0.0,
        }
    }
}

/// [`Keep::max_range_m`]'s default, metres.
pub const DEFAULT_MAX_RANGE_M: f32 = 20.0;

impl Keep {
    /// Everything is fused (the map before the keep rule existed).
    pub const ALL: Keep = Keep {
        max_range_m: f32::INFINITY,
        min_confidence: 0.0,
    };

    /// Whether a Gaussian at bin-frame position `mean` with `confidence` is fused. A NaN
    /// distance or confidence is not.
    pub fn keeps(&self, mean: Vec3, confidence: f32) -> bool {
        mean.length() <= self.max_range_m && confidence >= self.min_confidence
    }

    /// A bin map's sky layer: its Gaussians beyond `max_range_m` (finite centres), in the
    /// bin frame. They stay out of the world map's geometry, but a consumer rendering views
    /// near the bin draws them behind the map, as the bin map itself would.
    pub fn backdrop(&self, set: &GaussianSet) -> GaussianSet {
        let mut out = GaussianSet::default();
        for i in 0..set.len() {
            let g = set.get(i);
            if g.mean.is_finite() && g.mean.length() > self.max_range_m {
                out.push(g);
            }
        }
        out
    }
}

/// The map's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FusionConfig {
    /// Edge of a hash cell, metres: the scale at which overlapping bins compete.
    pub cell_size: f64,
    /// Gaussians with a lower opacity are not taken in.
    pub opacity_floor: f32,
    /// The most Gaussians the map holds (memory budget); see the module doc for eviction.
    pub max_gaussians: usize,
    /// Which Gaussians of a bin map are fused at all.
    pub keep: Keep,
    /// Side of the square ground tiles a long drive's map is paged to disk by, metres
    /// (rounded to whole 16 m ground columns: [`FusionConfig::tile_side`]).
    pub tile_m: f64,
}

impl Default for FusionConfig {
    /// 0.2 m cells, opacity floor 0.01, two million Gaussians, [`Keep::default`], 64 m
    /// tiles.
    fn default() -> Self {
        Self {
            cell_size: 0.2,
            opacity_floor: 0.01,
            max_gaussians: 2_000_000,
            keep: Keep::default(),
            tile_m: 64.0,
        }
    }
}

impl FusionConfig {
    /// Errors naming the first setting out of range.
    pub fn validate(&self) -> Result<(), FusionError> {
        let what = if !(self.cell_size.is_finite() && self.cell_size > 0.0) {
            "cell_size must be finite and positive"
        } else if !(0.0..=1.0).contains(&self.opacity_floor) {
            "opacity_floor must be in [0, 1]"
        } else if self.keep.max_range_m.is_nan() || self.keep.max_range_m <= 0.0 {
            "keep.max_range_m must be positive"
        } else if !(0.0..=1.0).contains(&self.keep.min_confidence) {
            "keep.min_confidence must be in [0, 1]"
        } else if !(self.tile_m.is_finite() && self.tile_m > 0.0 && self.tile_m <= 1.0e5) {
            "tile_m must be positive and at most 100 km"
        } else {
            return Ok(());
        };
        Err(FusionError::InvalidConfig { what })
    }
}

/// Input the map refuses (the map is unchanged).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum FusionError {
    /// A setting is out of range.
    #[error("invalid fusion config: {what}")]
    InvalidConfig {
        /// What is wrong.
        what: &'static str,
    },
    /// A bin pose is not a finite rigid transform.
    #[error("bin {bin_id}: pose {reason}")]
    BadPose {
        /// The bin.
        bin_id: u64,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A bin's Gaussian set has arrays of different lengths.
    #[error("bin {bin_id}: {source}")]
    BadSet {
        /// The bin.
        bin_id: u64,
        /// Which array differs.
        source: LengthMismatch,
    },
}

/// Why `pose` is not a finite rigid transform (rotation orthonormal to 1e-6, determinant +1),
/// or `None` when it is one.
pub fn pose_problem(pose: &DAffine3) -> Option<&'static str> {
    let m = pose.matrix3;
    if !(m.is_finite() && pose.translation.is_finite()) {
        return Some("has a NaN or infinite entry");
    }
    let err = m.transpose() * m - DMat3::IDENTITY;
    let off = [err.x_axis, err.y_axis, err.z_axis]
        .iter()
        .map(|c| c.abs().max_element())
        .fold(0.0, f64::max);
    if off > 1e-6 || m.determinant() < 0.0 {
        return Some("is not a rotation plus translation");
    }
    None
}

/// The fused world map: Gaussians by id plus the cell hash that the fusion rule and the
/// budget act on.
///
/// The Gaussians live in a persistent ordered map ([`imbl::OrdMap`]): a copy of the stored
/// parts ([`GlobalMap::stored`]) shares them, so the node hands the map to its compactor
/// without copying it, and the map then copies only the tree nodes it changes while the copy
/// is alive.
#[derive(Clone, Debug)]
pub struct GlobalMap {
    config: FusionConfig,
    gaussians: OrdMap<GaussianId, WorldGaussian>,
    cells: CellIndex,
    paged: BTreeMap<TileKey, PagedTile>,
    next_id: u64,
    last_bin_id: Option<u64>,
    latest_origin: Option<DVec3>,
    increments: u64,
    epoch: u64,
}

impl GlobalMap {
    /// An empty map; errors when a setting is out of range.
    pub fn new(config: FusionConfig) -> Result<Self, FusionError> {
        config.validate()?;
        Ok(Self {
            config,
            gaussians: OrdMap::new(),
            cells: CellIndex::new(config.cell_size),
            paged: BTreeMap::new(),
            next_id: 0,
            last_bin_id: None,
            latest_origin: None,
            increments: 0,
            epoch: 0,
        })
    }

    /// The map's settings.
    pub fn config(&self) -> &FusionConfig {
        &self.config
    }

    /// Number of Gaussians in memory (paged-out tiles not counted: [`GlobalMap::total_len`]).
    pub fn len(&self) -> usize {
        self.gaussians.len()
    }

    /// True when the map holds no Gaussian.
    pub fn is_empty(&self) -> bool {
        self.gaussians.is_empty()
    }

    /// Number of occupied cells.
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    /// The last bin inserted, `None` before the first.
    pub fn last_bin_id(&self) -> Option<u64> {
        self.last_bin_id
    }

    /// How many bins were taken in (successful [`GlobalMap::insert_bin`] calls): the sequence
    /// number of the last increment, which a saved map keeps so a restored one continues it.
    pub fn increments(&self) -> u64 {
        self.increments
    }

    /// How many times this map was resumed from a saved file ([`GlobalMap::resume`]); 0 for
    /// a map that never was. Saved with the map.
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    /// Marks the map as resumed by a new run (a node restored it): the epoch goes up by one.
    pub fn resume(&mut self) {
        self.epoch += 1;
    }

    /// The world position of the latest non-empty bin's origin (the eviction anchor).
    pub fn latest_origin(&self) -> Option<DVec3> {
        self.latest_origin
    }

    /// The Gaussian with id `id`, if the map holds it.
    pub fn get(&self, id: GaussianId) -> Option<&WorldGaussian> {
        self.gaussians.get(&id)
    }

    /// The Gaussians in id order.
    pub fn gaussians(&self) -> impl Iterator<Item = (GaussianId, &WorldGaussian)> {
        self.gaussians.iter().map(|(&id, g)| (id, g))
    }

    /// The Gaussians whose centres lie in the ground box `min`-`max` (world x-y, metres,
    /// any height), in id order. It visits only the part of the map near the box, so its
    /// cost follows the box's content, not the map's size.
    pub fn gaussians_in(&self, min: DVec2, max: DVec2) -> Vec<(GaussianId, &WorldGaussian)> {
        let mut ids = self.cells.ids_near(min, max);
        ids.sort_unstable();
        ids.into_iter()
            .filter_map(|id| self.gaussians.get(&id).map(|g| (id, g)))
            .filter(|(_, g)| {
                let p = g.position.truncate();
                p.cmpge(min).all() && p.cmple(max).all()
            })
            .collect()
    }

    /// Everything in the map, sorted by id: what a late subscriber starts from.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot::of(self.gaussians.iter(), self.last_bin_id)
    }

    /// Fuses one bin map (`set` in the bin's frame, `bin_to_world` its pose) into the map by
    /// the rule in the module doc and returns what changed. A bad pose or a set with
    /// mismatched arrays is an error and changes nothing; bad Gaussians are skipped and
    /// counted; an empty bin changes nothing but the last bin id and the increment count.
    pub fn insert_bin(
        &mut self,
        bin_id: u64,
        set: &GaussianSet,
        bin_to_world: DAffine3,
    ) -> Result<Increment, FusionError> {
        if let Some(reason) = pose_problem(&bin_to_world) {
            return Err(FusionError::BadPose { bin_id, reason });
        }
        set.check_lengths()
            .map_err(|source| FusionError::BadSet { bin_id, source })?;
        self.last_bin_id = Some(bin_id);
        self.increments += 1;
        let mut stats = InsertStats {
            input: set.len(),
            ..InsertStats::default()
        };
        if set.is_empty() {
            return Ok(Increment {
                bin_id,
                stats,
                ..Increment::default()
            });
        }
        self.latest_origin = Some(bin_to_world.translation);

        let candidates = self.to_world(bin_id, set, bin_to_world, &mut stats);
        let mut bin_max: HashMap<CellKey, f32> = HashMap::default();
        for (key, g) in &candidates {
            let m = bin_max.entry(*key).or_insert(g.confidence);
            *m = m.max(g.confidence);
        }
        let mut removed = Vec::new();
        for (key, new_max) in &bin_max {
            if let Some(cell) = self.cells.get(key) {
                if *new_max > cell.max_confidence {
                    stats.replaced += cell.ids.len();
                    removed.extend(self.remove_cell(*key));
                }
            }
        }
        let first_new = self.next_id;
        let mut added = Vec::new();
        let mut taken: HashMap<CellKey, bool> = HashMap::default();
        for (key, g) in candidates {
            let accept = *taken
                .entry(key)
                .or_insert_with(|| !self.cells.contains(&key));
            if !accept {
                stats.dropped_lower_confidence += 1;
                continue;
            }
            let id = GaussianId(self.next_id);
            self.next_id += 1;
            self.cells.push(key, id, g.confidence);
            self.gaussians.insert(id, g);
            added.push(id);
        }

        let evicted = self.enforce_budget();
        stats.evicted = evicted.len();
        // Ids at or above `first_new` are this bin's: evicted ones were never published.
        removed.extend(evicted.into_iter().filter(|id| id.0 < first_new));
        removed.sort_unstable();
        let added = added
            .into_iter()
            .filter_map(|id| self.gaussians.get(&id).map(|g| (id, *g)))
            .collect();
        Ok(Increment {
            bin_id,
            added,
            removed,
            stats,
        })
    }

    /// The bin's valid Gaussians in world coordinates with their cells, in input order.
    fn to_world(
        &self,
        bin_id: u64,
        set: &GaussianSet,
        pose: DAffine3,
        stats: &mut InsertStats,
    ) -> Vec<(CellKey, WorldGaussian)> {
        let pose_rotation = DQuat::from_mat3(&pose.matrix3);
        let mut out = Vec::with_capacity(set.len());
        for i in 0..set.len() {
            let l = set.get(i);
            let finite = l.mean.is_finite()
                && l.log_scale.is_finite()
                && l.rotation.is_finite()
                && l.opacity.is_finite()
                && l.color.is_finite()
                && l.confidence.is_finite();
            if !finite {
                stats.skipped_invalid += 1;
                continue;
            }
            let (opacity, confidence) = (l.opacity.clamp(0.0, 1.0), l.confidence.clamp(0.0, 1.0));
            if opacity < self.config.opacity_floor {
                stats.pruned_opacity += 1;
                continue;
            }
            if !self.config.keep.keeps(l.mean, confidence) {
                stats.not_kept += 1;
                continue;
            }
            let local_rotation = l.rotation.as_dquat();
            let local_rotation = if local_rotation.length_squared() > 0.0 {
                local_rotation.normalize()
            } else {
                DQuat::IDENTITY
            };
            let position = pose.transform_point3(l.mean.as_dvec3());
            let g = WorldGaussian {
                position,
                log_scale: l.log_scale,
                rotation: (pose_rotation * local_rotation).normalize().as_quat(),
                opacity,
                color: l.color,
                confidence,
                bin_id,
            };
            out.push((cell_of(position, self.config.cell_size), g));
        }
        out
    }

    /// Removes a whole cell and its Gaussians; returns their ids.
    fn remove_cell(&mut self, key: CellKey) -> Vec<GaussianId> {
        let ids = self.cells.remove(key);
        for id in &ids {
            self.gaussians.remove(id);
        }
        ids
    }

    /// Evicts whole cells until the map is within budget, ground column by ground column
    /// (about 16 m squares, the farthest from the latest origin first), within a column the
    /// farthest cell first; returns the evicted ids. Ordering columns rather than every cell
    /// keeps the cost to the number of columns, not the map's size.
    fn enforce_budget(&mut self) -> Vec<GaussianId> {
        let mut evicted = Vec::new();
        if self.gaussians.len() <= self.config.max_gaussians {
            return evicted;
        }
        let anchor = self.latest_origin.unwrap_or(DVec3::ZERO);
        for column in self.cells.columns_farthest_first(anchor) {
            let cells = self.cells.column_cells(column);
            for key in eviction_order(cells, anchor, self.config.cell_size) {
                if self.gaussians.len() <= self.config.max_gaussians {
                    return evicted;
                }
                evicted.extend(self.remove_cell(key));
            }
        }
        evicted
    }

    /// A copy of the parts the map's file stores, for writing it elsewhere (the compactor's
    /// thread): O(1) in the map's size, since it shares the Gaussians with the map.
    pub fn stored(&self) -> StoredMap {
        StoredMap {
            config: self.config,
            gaussians: self.gaussians.clone(),
            paged: self.paged.clone(),
            next_id: self.next_id,
            last_bin_id: self.last_bin_id,
            latest_origin: self.latest_origin,
            increments: self.increments,
            epoch: self.epoch,
        }
    }

    /// Rebuilds a map from stored parts (the cells follow from the positions); used by
    /// restore after the parts were checked.
    fn from_parts(parts: StoredMap) -> Self {
        let mut cells = CellIndex::new(parts.config.cell_size);
        for (&id, g) in parts.gaussians.iter() {
            let key = cell_of(g.position, parts.config.cell_size);
            cells.push(key, id, g.confidence);
        }
        Self {
            config: parts.config,
            gaussians: parts.gaussians,
            cells,
            paged: parts.paged,
            next_id: parts.next_id,
            last_bin_id: parts.last_bin_id,
            latest_origin: parts.latest_origin,
            increments: parts.increments,
            epoch: parts.epoch,
        }
    }
}

/// The parts of a map its file stores (everything but the cell hash, which follows from
/// the positions). Taken from a live map ([`GlobalMap::stored`]) it shares the map's
/// Gaussians, so it costs O(1) to take and can be written while the map goes on changing.
#[derive(Clone, Debug)]
pub struct StoredMap {
    config: FusionConfig,
    gaussians: OrdMap<GaussianId, WorldGaussian>,
    paged: BTreeMap<TileKey, PagedTile>,
    next_id: u64,
    last_bin_id: Option<u64>,
    latest_origin: Option<DVec3>,
    increments: u64,
    epoch: u64,
}

#[cfg(test)]
#[path = "range_tests.rs"]
mod range_tests;
