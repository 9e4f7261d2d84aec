//! The view's copy of the map, cut into square ground tiles, so that neither the view's
//! memory nor what its page loads grows with the length of the drive.
//!
//! Tiles within [`TileRules::keep_m`] of the latest bin are *held*: the view applies the
//! node's increments to them Gaussian by Gaussian. A held tile the vehicle has left farther
//! behind is *let go*: its Gaussians leave the view's memory and only its key, count and
//! version stay. The node keeps the tile (in memory or paged to its disk), so when the page
//! asks for a let-go tile near its camera the view fetches it from the node's region query
//! ([`ViewTiles::wanted`], [`ViewTiles::fetched`]) and keeps a bounded cache of such tiles.
//! An increment that adds to a let-go tile bumps its version (so a cached copy is fetched
//! again) but is not applied; a removal of a Gaussian the view no longer holds is skipped.
//!
//! The page asks for the tiles near its camera within a Gaussian budget
//! ([`ViewTiles::near`]) and loads each as its own splat scene, so a change reloads the
//! tiles it touched and nothing else.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::sync::Arc;

use glam::{DVec2, DVec3};

use crate::fusion::{tile_distance, GaussianId, Increment, Snapshot, TileKey, WorldGaussian};

/// Let-go tiles remembered at most (their key, count and version: 40 bytes each); beyond
/// it the farthest from the vehicle are forgotten.
const MAX_LET_GO: usize = 1 << 16;
/// Tiles waiting to be fetched at most.
const MAX_WANTED: usize = 64;

/// The `side`-metre ground tile of a world position: `floor` of x and y over the side (a
/// non-finite coordinate lands in tile 0; casts saturate far out).
pub fn ground_tile(p: DVec3, side: f64) -> TileKey {
    let k = |v: f64| {
        let t = (v / side).floor();
        if t.is_finite() {
            t as i64
        } else {
            0
        }
    };
    (k(p.x), k(p.y))
}

/// The view's tile settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileRules {
    /// Tile side, metres (the view's own grid, independent of the node's).
    pub side_m: f64,
    /// Tiles farther than this from the latest bin are let go, metres.
    pub keep_m: f64,
    /// Gaussians of fetched let-go tiles cached at most.
    pub cache_gaussians: usize,
}

impl Default for TileRules {
    /// 64 m tiles, held within 250 m of the vehicle, 2 M fetched Gaussians cached.
    fn default() -> Self {
        Self {
            side_m: 64.0,
            keep_m: 250.0,
            cache_gaussians: 2_000_000,
        }
    }
}

/// What the view knows of one tile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileInfo {
    /// The view's map version when the tile last changed.
    pub version: u64,
    /// Its Gaussians (for a let-go tile: as last known).
    pub gaussians: usize,
    /// True when the view holds its Gaussians.
    pub held: bool,
}

/// A tile listed for a page ([`ViewTiles::near`]) and how many of its Gaussians it draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NearTile {
    /// The tile.
    pub key: TileKey,
    /// Its version and size.
    pub info: TileInfo,
    /// Gaussians of it the page draws: all of them, or fewer for the last tile of a budget.
    pub take: usize,
}

/// The indices of the `take` most opaque of `gaussians`, in their order (ties keep the
/// earlier): the part of a tile a page draws when its budget cuts the tile, since the
/// opaque Gaussians are the ones a picture shows. All of them when `take` reaches the
/// length. NaN opacities count as the least opaque.
pub fn most_opaque(gaussians: &[WorldGaussian], take: usize) -> Vec<usize> {
    if take >= gaussians.len() {
        return (0..gaussians.len()).collect();
    }
    let opacity = |i: usize| {
        let o = gaussians[i].opacity;
        if o.is_nan() {
            f32::NEG_INFINITY
        } else {
            o
        }
    };
    let mut order: Vec<usize> = (0..gaussians.len()).collect();
    // Only the first `take` need finding, not a whole sorted order (ties by index make the
    // order total, so the set is the same).
    if take > 0 {
        order.select_nth_unstable_by(take - 1, |&a, &b| {
            opacity(b).total_cmp(&opacity(a)).then(a.cmp(&b))
        });
    }
    order.truncate(take);
    order.sort_unstable();
    order
}

/// A held tile.
#[derive(Debug, Default)]
struct Tile {
    version: u64,
    gaussians: BTreeMap<GaussianId, WorldGaussian>,
}

/// Why an update could not be applied (nothing changed).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TilesError {
    /// A removal names a Gaussian the view never saw (and it has let no tile go).
    #[error("bin {bin_id} removes Gaussian {id}, which the view does not hold")]
    UnknownId {
        /// The increment's bin.
        bin_id: u64,
        /// The id.
        id: u64,
    },
    /// An addition reuses an id the view holds.
    #[error("bin {bin_id} adds Gaussian {id} twice")]
    DuplicateId {
        /// The increment's bin.
        bin_id: u64,
        /// The id.
        id: u64,
    },
}

/// The tiled copy; see the module documentation.
#[derive(Debug)]
pub struct ViewTiles {
    rules: TileRules,
    held: HashMap<TileKey, Tile>,
    tile_of_id: HashMap<GaussianId, TileKey>,
    let_go: BTreeMap<TileKey, TileInfo>,
    /// Fetched let-go tiles: key, the version fetched for, the Gaussians; oldest first.
    cache: VecDeque<(TileKey, u64, Arc<Vec<WorldGaussian>>)>,
    cached_gaussians: usize,
    wanted: BTreeSet<TileKey>,
    len: usize,
    skipped: u64,
}

impl Default for ViewTiles {
    fn default() -> Self {
        Self::new(TileRules::default())
    }
}

impl ViewTiles {
    /// An empty copy with these rules (a side or keep range that is not positive and finite
    /// is replaced by the default's).
    pub fn new(rules: TileRules) -> Self {
        let default = TileRules::default();
        let ok = |v: f64| v.is_finite() && v > 0.0;
        let rules = TileRules {
            side_m: if ok(rules.side_m) {
                rules.side_m
            } else {
                default.side_m
            },
            keep_m: if ok(rules.keep_m) {
                rules.keep_m
            } else {
                default.keep_m
            },
            cache_gaussians: rules.cache_gaussians,
        };
        Self {
            rules,
            held: HashMap::new(),
            tile_of_id: HashMap::new(),
            let_go: BTreeMap::new(),
            cache: VecDeque::new(),
            cached_gaussians: 0,
            wanted: BTreeSet::new(),
            len: 0,
            skipped: 0,
        }
    }

    /// The rules in force.
    pub fn rules(&self) -> TileRules {
        self.rules
    }

    /// The tile of a world position (`floor` of x and y over the side; a non-finite
    /// coordinate lands in tile 0).
    pub fn tile_of(&self, p: DVec3) -> TileKey {
        ground_tile(p, self.rules.side_m)
    }

    /// A tile's ground box, world metres.
    pub fn bounds(&self, tile: TileKey) -> (DVec2, DVec2) {
        let lo = DVec2::new(tile.0 as f64, tile.1 as f64) * self.rules.side_m;
        (lo, lo + self.rules.side_m)
    }

    /// Gaussians held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when no Gaussian is held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Held tiles and let-go tiles.
    pub fn tile_counts(&self) -> (usize, usize) {
        (self.held.len(), self.let_go.len())
    }

    /// What the view knows of one tile.
    pub fn info(&self, key: TileKey) -> Option<TileInfo> {
        match self.held.get(&key) {
            Some(t) => Some(TileInfo {
                version: t.version,
                gaussians: t.gaussians.len(),
                held: true,
            }),
            None => self.let_go.get(&key).copied(),
        }
    }

    /// True when the tile was let go (the node has it, the view does not).
    pub fn is_let_go(&self, key: TileKey) -> bool {
        self.let_go.contains_key(&key)
    }

    /// Removals of Gaussians the view had let go (skipped).
    pub fn skipped_removals(&self) -> u64 {
        self.skipped
    }

    /// Every held Gaussian (tiles in key order, ids increasing within a tile).
    pub fn gaussians(&self) -> impl Iterator<Item = &WorldGaussian> {
        let mut keys: Vec<&TileKey> = self.held.keys().collect();
        keys.sort();
        keys.into_iter()
            .flat_map(|k| self.held[k].gaussians.values())
    }

    /// Replaces what is held with a whole-map snapshot stamped `version`. Let-go tiles the
    /// snapshot does not cover stay known (the node keeps them on disk).
    pub fn replace(&mut self, snapshot: &Snapshot, version: u64) {
        self.held.clear();
        self.tile_of_id.clear();
        self.len = 0;
        for (id, g) in &snapshot.gaussians {
            self.insert(*id, *g, version);
        }
        for key in self.held.keys() {
            self.let_go.remove(key);
        }
    }

    /// Applies one increment stamped `version`: removals, then additions. On error nothing
    /// changes.
    pub fn apply(&mut self, inc: &Increment, version: u64) -> Result<(), TilesError> {
        let strict = self.let_go.is_empty();
        let removed: BTreeSet<GaussianId> = inc.removed.iter().copied().collect();
        if strict {
            if let Some(id) = inc
                .removed
                .iter()
                .find(|id| !self.tile_of_id.contains_key(id))
            {
                return Err(TilesError::UnknownId {
                    bin_id: inc.bin_id,
                    id: id.0,
                });
            }
        }
        let mut seen = BTreeSet::new();
        for (id, _) in &inc.added {
            let held = self.tile_of_id.contains_key(id) && !removed.contains(id);
            if held || !seen.insert(*id) {
                return Err(TilesError::DuplicateId {
                    bin_id: inc.bin_id,
                    id: id.0,
                });
            }
        }
        for id in &inc.removed {
            match self.tile_of_id.remove(id) {
                Some(key) => {
                    if let Some(tile) = self.held.get_mut(&key) {
                        tile.gaussians.remove(id);
                        tile.version = version;
                        self.len -= 1;
                        if tile.gaussians.is_empty() {
                            self.held.remove(&key);
                        }
                    }
                }
                None => self.skipped += 1,
            }
        }
        for (id, g) in &inc.added {
            let key = self.tile_of(g.position);
            match self.let_go.get_mut(&key) {
                Some(info) => {
                    info.version = version;
                    info.gaussians += 1;
                }
                None => self.insert(*id, *g, version),
            }
        }
        Ok(())
    }

    fn insert(&mut self, id: GaussianId, g: WorldGaussian, version: u64) {
        let key = self.tile_of(g.position);
        let tile = self.held.entry(key).or_default();
        tile.version = version;
        if tile.gaussians.insert(id, g).is_none() {
            self.len += 1;
        }
        self.tile_of_id.insert(id, key);
    }

    /// Takes note of tiles the node keeps on its disk (key and Gaussian count, as a
    /// whole-map snapshot's reply names them) as let-go tiles stamped `version`, so the page
    /// can list them and the view fetch them; tiles the view holds or knows already are
    /// left as they are, and none is added beyond `MAX_LET_GO`.
    pub fn paged_on_node(&mut self, tiles: &[(TileKey, usize)], version: u64) {
        for &(key, gaussians) in tiles {
            if self.let_go.len() >= MAX_LET_GO {
                break;
            }
            if !self.held.contains_key(&key) {
                self.let_go.entry(key).or_insert(TileInfo {
                    version,
                    gaussians,
                    held: false,
                });
            }
        }
    }

    /// Lets go of the held tiles farther than the keep range from `vehicle`, and forgets
    /// the farthest let-go tiles beyond `MAX_LET_GO`.
    pub fn let_go_far_from(&mut self, vehicle: DVec3) {
        let side = self.rules.side_m;
        let far: Vec<TileKey> = self
            .held
            .keys()
            .filter(|k| tile_distance(**k, side, vehicle) > self.rules.keep_m)
            .copied()
            .collect();
        for key in far {
            let Some(tile) = self.held.remove(&key) else {
                continue;
            };
            for id in tile.gaussians.keys() {
                self.tile_of_id.remove(id);
            }
            self.len -= tile.gaussians.len();
            let info = TileInfo {
                version: tile.version,
                gaussians: tile.gaussians.len(),
                held: false,
            };
            self.let_go.insert(key, info);
        }
        if self.let_go.len() > MAX_LET_GO {
            let mut by_distance: Vec<(f64, TileKey)> = self
                .let_go
                .keys()
                .map(|k| (tile_distance(*k, side, vehicle), *k))
                .collect();
            by_distance.sort_by(|a, b| b.0.total_cmp(&a.0));
            let excess = self.let_go.len() - MAX_LET_GO;
            for (_, key) in by_distance.into_iter().take(excess) {
                self.let_go.remove(&key);
            }
        }
    }

    /// The tiles (held or let go) within `radius` metres of `point`, nearest first, until
    /// `budget` Gaussians are listed: each tile takes all its Gaussians while they fit and
    /// the first that does not fit takes what is left (its most opaque, see
    /// `most_opaque`), so a page's budget bounds what it draws even when one tile holds
    /// more.
    pub fn near(&self, point: DVec3, radius: f64, budget: usize) -> Vec<NearTile> {
        let side = self.rules.side_m;
        let held = self.held.iter().map(|(k, t)| {
            let info = TileInfo {
                version: t.version,
                gaussians: t.gaussians.len(),
                held: true,
            };
            (*k, info)
        });
        let all = held.chain(self.let_go.iter().map(|(k, i)| (*k, *i)));
        let mut found: Vec<(f64, TileKey, TileInfo)> = all
            .map(|(k, i)| (tile_distance(k, side, point), k, i))
            .filter(|(d, _, _)| *d <= radius)
            .collect();
        found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut left = budget;
        let mut out = Vec::new();
        for (_, key, info) in found {
            if left == 0 {
                break;
            }
            let take = info.gaussians.min(left);
            left -= take;
            out.push(NearTile { key, info, take });
        }
        out
    }

    /// A tile's Gaussians with its version: held, or let go and fetched for its current
    /// version. A let-go tile not fetched yet is marked wanted and `None` is returned; so is
    /// an unknown tile.
    pub fn tile(&mut self, key: TileKey) -> Option<(u64, Arc<Vec<WorldGaussian>>)> {
        if let Some(t) = self.held.get(&key) {
            return Some((t.version, Arc::new(t.gaussians.values().copied().collect())));
        }
        let info = *self.let_go.get(&key)?;
        let cached = self
            .cache
            .iter()
            .find(|(k, v, _)| *k == key && *v == info.version);
        if let Some((_, v, g)) = cached {
            return Some((*v, g.clone()));
        }
        if self.wanted.len() < MAX_WANTED {
            self.wanted.insert(key);
        }
        None
    }

    /// The let-go tiles the page asked for that are not fetched yet (they stay wanted until
    /// [`ViewTiles::fetched`] gets them).
    pub fn wanted(&self) -> Vec<TileKey> {
        self.wanted.iter().copied().collect()
    }

    /// Takes in what the node answered for the `tiles` asked: the Gaussians of each still
    /// let-go tile are cached for its current version (Gaussians of other tiles are
    /// ignored); the oldest cached tiles go first beyond the cache's budget.
    pub fn fetched(&mut self, tiles: &[TileKey], gaussians: &[(GaussianId, WorldGaussian)]) {
        let mut by_tile: BTreeMap<TileKey, Vec<WorldGaussian>> = BTreeMap::new();
        for key in tiles {
            self.wanted.remove(key);
            if self.let_go.contains_key(key) {
                by_tile.insert(*key, Vec::new());
            }
        }
        for (_, g) in gaussians {
            if let Some(list) = by_tile.get_mut(&self.tile_of(g.position)) {
                list.push(*g);
            }
        }
        for (key, list) in by_tile {
            let info = self.let_go.get_mut(&key).expect("checked above");
            info.gaussians = list.len();
            let version = info.version;
            let mut dropped = 0;
            self.cache.retain(|(k, _, g)| {
                let keep = *k != key;
                if !keep {
                    dropped += g.len();
                }
                keep
            });
            self.cached_gaussians -= dropped;
            self.cached_gaussians += list.len();
            self.cache.push_back((key, version, Arc::new(list)));
        }
        while self.cached_gaussians > self.rules.cache_gaussians {
            let Some((_, _, g)) = self.cache.pop_front() else {
                break;
            };
            self.cached_gaussians -= g.len();
        }
    }
}

#[cfg(test)]
#[path = "tiles_tests.rs"]
mod tests;
