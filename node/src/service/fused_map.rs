//! The global map the node fuses into and what keeps it: the store that journals each bin's
//! change ahead of its publication ([`crate::store::map_store`]), the thread handing freed
//! memory back, and what answers read from it (snapshots, regions of the whole map, the
//! paged tiles a snapshot does not hold). The publishing side is [`super::outputs`].

use renderer::GaussianSet;

use super::region::RegionQuery;
use crate::counters::Counters;
use crate::fusion::{
    encode_map_snapshot, snapshot_message, FusionError, GaussianId, GlobalMap, Increment, Snapshot,
    WorldGaussian,
};
use crate::memory::Releaser;
use crate::msg::map_update::MapUpdate;
use crate::msg::std_msgs::Header;
use crate::store::map_files::{gaussians_in_whole, RegionReadError};
use crate::store::map_store::{MapStore, Recorded};

/// Paged tiles a whole-map snapshot reply lists at most (about 30 bytes each).
pub const MAX_LISTED_TILES: usize = 100_000;

/// A region's Gaussians cut into pages ([`FusedMap::region_pages`]).
pub(super) struct RegionPages {
    /// The pages, in id order.
    pub pages: Vec<Vec<(GaussianId, WorldGaussian)>>,
    /// Gaussians in all pages.
    pub total: usize,
}

/// The fused global map and what keeps it.
pub(super) struct FusedMap {
    /// The map.
    pub map: GlobalMap,
    /// The map's journal and tiles, when the node has an out folder.
    store: Option<MapStore>,
    /// The thread returning freed memory to the system, when the node runs one.
    pub releaser: Option<Releaser>,
    /// The source stamp of the latest bin fused (what a snapshot of the map is stamped
    /// with; 0 before the first).
    pub latest_source_ns: i64,
    /// A resumed map's snapshot is still to be published (before the first increment).
    pub resume_pending: bool,
}

impl FusedMap {
    /// `map` (new or resumed), journaled into `store` when there is one.
    pub fn new(map: GlobalMap, store: Option<MapStore>) -> Self {
        Self {
            map,
            store,
            releaser: None,
            latest_source_ns: 0,
            resume_pending: false,
        }
    }

    /// Fuses `set`, a bin's map in its bin frame, at `bin_to_world` (the tiles it reaches
    /// read back from disk first) and journals the change; errors are reported on stderr
    /// and counted (`error/checkpoint`). Returns the increment and the map's sequence
    /// number after it.
    pub fn fuse(
        &mut self,
        bin_id: u64,
        set: &GaussianSet,
        bin_to_world: glam::DAffine3,
        source_ns: i64,
        counters: &mut Counters,
    ) -> Result<(Increment, u64), FusionError> {
        if let Some(store) = &mut self.store {
            if let Err(e) = store.prepare(&mut self.map, bin_to_world.translation) {
                eprintln!("reading paged tiles back failed: {e}");
                counters.add("error/checkpoint", 1);
            }
        }
        let fused = self.map.insert_bin(bin_id, set, bin_to_world);
        self.latest_source_ns = source_ns;
        if let Ok(inc) = &fused {
            self.journal(inc, counters);
        }
        let sequence = self.map.increments();
        fused.map(|inc| (inc, sequence))
    }

    /// Whether the journal is failing (its records are kept to be written again).
    pub fn failing(&self) -> bool {
        self.store.as_ref().is_some_and(MapStore::failing)
    }

    /// Writes again what the journal failed to take; whether everything fused is durable
    /// now (always, without a store).
    pub fn flush(&mut self) -> bool {
        match &mut self.store {
            Some(store) => store.flush(&self.map).is_ok(),
            None => true,
        }
    }

    /// The memory releaser's counters, set in `counters`.
    pub fn releaser_counts_into(&self, counters: &mut Counters) {
        if let Some(r) = &self.releaser {
            for (name, value) in r.counts() {
                counters.set(name, value);
            }
        }
    }

    /// Journals a fused bin's change (and the tiles paged with it) before the bin is
    /// published; a failure is reported on stderr and counted (`error/checkpoint`), and the
    /// store keeps the record to write again ([`MapStore::failing`]).
    fn journal(&mut self, inc: &Increment, counters: &mut Counters) {
        let Some(store) = &mut self.store else {
            return;
        };
        match store.record(&mut self.map, inc) {
            Ok(Recorded::Durable) => counters.add("map/checkpoints", 1),
            Ok(_) => {}
            Err(e) => {
                eprintln!("checkpoint failed: {e}");
                counters.add("error/checkpoint", 1);
            }
        }
        for (name, value) in store.counts() {
            counters.set(name, value);
        }
    }

    /// Syncs the journal and waits for its compactor, before the map is saved whole.
    pub fn close_store(&mut self, counters: &mut Counters) {
        if let Some(mut store) = self.store.take() {
            if let Err(e) = store.finish() {
                eprintln!("checkpoint failed: {e}");
                counters.add("error/checkpoint", 1);
            }
            for (name, value) in store.counts() {
                counters.set(name, value);
            }
        }
    }

    /// The whole map in memory as an encoded MapUpdate snapshot at the current sequence
    /// number, written straight from the map ([`encode_map_snapshot`]).
    pub fn snapshot(&self, header: Header) -> Result<Vec<u8>, crate::msg::ConvertError> {
        encode_map_snapshot(&self.map, header)
    }

    /// The attachment of a whole-map snapshot reply: the tiles it does not hold because
    /// they are paged to disk, so that a subscriber resetting from it knows they exist and
    /// can ask for them by region: `{"tile_m": side, "paged_tiles": [[x, y, gaussians],
    /// ...]}` (tile `(x, y)` covers `[x, x + 1) * side` by `[y, y + 1) * side`, world
    /// metres), at most [`MAX_LISTED_TILES`] of them (`"truncated": true` beyond).
    pub fn snapshot_attachment(&self) -> String {
        let paged = self.map.paged_tiles();
        let listed: Vec<[i64; 3]> = paged
            .iter()
            .take(MAX_LISTED_TILES)
            .map(|(k, t)| [k.0, k.1, t.count as i64])
            .collect();
        serde_json::json!({
            "tile_m": self.map.config().tile_side(),
            "paged_tiles": listed,
            "truncated": paged.len() > MAX_LISTED_TILES,
        })
        .to_string()
    }

    /// The Gaussians of `region`, in id order, cut into pages of its page size (one empty
    /// page when there are none): those in memory and those of the tiles on disk the region
    /// meets. Refused when the region may hold more than the map's budget in memory.
    pub fn region_pages(&self, region: &RegionQuery) -> Result<RegionPages, RegionReadError> {
        let budget = self.map.config().max_gaussians as u64;
        let tiles = self
            .store
            .as_ref()
            .map(MapStore::tiles_dir)
            .unwrap_or_default();
        let found = gaussians_in_whole(&self.map, &tiles, region.min, region.max, budget)?;
        let total = found.len();
        let mut pages: Vec<Vec<(GaussianId, WorldGaussian)>> =
            found.chunks(region.page_size).map(|c| c.to_vec()).collect();
        if pages.is_empty() {
            pages.push(Vec::new());
        }
        Ok(RegionPages { pages, total })
    }

    /// One page of a region as a MapUpdate snapshot at the current sequence number.
    pub fn region_page(
        &self,
        page: Vec<(GaussianId, WorldGaussian)>,
        header: Header,
    ) -> Result<MapUpdate, crate::msg::ConvertError> {
        let snap = Snapshot {
            last_bin_id: self.map.last_bin_id(),
            gaussians: page,
        };
        snapshot_message(&snap, self.map.increments(), header)
    }
}
