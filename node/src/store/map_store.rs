//! The global map on disk while the node runs: every fused bin's change is appended to the
//! journal ([`crate::fusion::JournalWriter`]) and made durable before the bin is published,
//! and a background thread folds closed journal segments into the checkpoint (the base
//! file), off the publish path.
//!
//! Cost per bin: one journal record, the size of the bin's own change. The base is
//! rewritten only when the open segment holds at least as many bytes as the base (and at
//! least [`Compaction::min_bytes`]): the rewrite then costs no more bytes than the journal
//! it folds in, so the bytes written per bin stay within about twice the bin's change
//! however large the map grows, and a restore replays at most about one base's worth of
//! journal. When the node closes a segment it hands the compactor a copy of the map as it
//! stands after the segment's last record ([`GlobalMap::stored`]); the compactor writes it
//! as the base, atomically, and only then removes the segments it covers and the tile files
//! no later record names, so a crash at any point leaves a base and segments that restore
//! every published bin ([`super::map_files::restore`]). The copy shares the map's Gaussians
//! (a persistent tree), so the compaction neither reads the base back nor replays the
//! journal, and holds in memory only the tree nodes the node changes while it writes (a bin
//! or two) and one chunk of the file.
//!
//! Failures (a full disk, an I/O error, a failed fsync) lose nothing: a record whose write
//! or sync failed is kept in memory and written again, to a new segment, by the next
//! record or [`MapStore::flush`] ([`crate::fusion::JournalWriter`]); the base is written
//! before any record, and retried until it is; a tile that cannot be written stays in
//! memory. The node publishes a bin only once its record is durable
//! (`super::outputs`), so what a crash can take is never something published.
//!
//! Paging ([`Paging`], [`crate::fusion::PagedTile`]): before a bin is fused, every tile on
//! disk within the paging radius of the bin's origin is read back into the map
//! ([`MapStore::prepare`]); after it, every tile in memory farther than the radius plus one
//! tile is written to its file and dropped from memory, and, while the map holds more than
//! three quarters of its budget in memory, the farthest tiles beyond the keep range too, so
//! the next bins fuse without evicting anything. Tile files are written and synced before
//! the journal record that names them. The base then holds only the tiles in memory, so
//! its size, the compactor's work and a restore's follow the resident map, not the whole
//! drive's.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::Instant;

use glam::DVec3;

use crate::fusion::{
    collect_garbage, segments, tile_distance, write_tile, GlobalMap, Increment, JournalWriter,
    PageEvent, StoreError, StoredMap, TileKey, JOURNAL_HEADER_BYTES as HEADER_BYTES,
};

use super::map_files::{checkpoint, CHECKPOINT, JOURNAL, TILES};
use crate::memory::release_freed_memory;

/// Which tiles of the map stay in memory while the node runs (the module doc has the rule).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Paging {
    /// Ground distance from a bin's origin within which tiles are in memory, metres (at
    /// least the keep range, so a bin never fuses into a tile on disk).
    pub radius_m: f64,
}

impl Default for Paging {
    /// 200 m: the map around the vehicle that a bin can meet, with room for the view.
    fn default() -> Self {
        Self { radius_m: 200.0 }
    }
}

/// When the journal is folded into the base.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Compaction {
    /// The open segment is closed and folded once it holds this many bytes and at least as
    /// many as the base.
    pub min_bytes: u64,
}

impl Default for Compaction {
    /// 64 MiB: a short drive keeps one segment and never rewrites its base while running.
    fn default() -> Self {
        Self {
            min_bytes: 64 << 20,
        }
    }
}

/// What became of a bin's record ([`MapStore::record`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Recorded {
    /// Durable: it survives a crash (and so does every record before it).
    Durable,
    /// Written, not yet synced: the sync is due after more bins (`every` above 1).
    Written,
    /// Nothing is journaled while running (`every` 0).
    NotKept,
    /// Kept in memory only: the store is failing, and the next flush writes it.
    Kept,
}

/// What the compactor has done, shared with the node's counters.
#[derive(Debug, Default)]
struct Folded {
    compactions: AtomicU64,
    failures: AtomicU64,
    base_bytes: AtomicU64,
    last_ms: AtomicU64,
}

/// The node's journal writer and its compactor.
pub struct MapStore {
    dir: PathBuf,
    every: u64,
    compaction: Compaction,
    writer: JournalWriter,
    /// The empty map with the node's settings, saved as the base before the first record
    /// when the folder holds none.
    empty: Option<GlobalMap>,
    unsynced_bins: u64,
    journal_bytes: u64,
    paging: Option<Paging>,
    paged_in: Vec<PageEvent>,
    tile_counts: [u64; 3],
    tile_failures: u64,
    failing: bool,
    tx: Option<mpsc::Sender<(PathBuf, StoredMap)>>,
    thread: Option<JoinHandle<()>>,
    folded: Arc<Folded>,
}

impl MapStore {
    /// A store in `dir` for `map` (new or resumed), syncing the journal after every `every`
    /// bins (0: nothing is written while running and nothing is paged; the node saves the
    /// map when it stops), paging tiles by `paging` (`None`: the whole map stays in memory).
    /// Segments a previous run left (after a crash) are handed to the compactor at once.
    pub fn new(
        dir: PathBuf,
        map: &GlobalMap,
        every: u64,
        compaction: Compaction,
        paging: Option<Paging>,
    ) -> Result<Self, StoreError> {
        let empty = match dir.join(CHECKPOINT).exists() {
            true => None,
            false => Some(GlobalMap::new(*map.config()).expect("a map's settings are valid")),
        };
        let folded = Arc::<Folded>::default();
        let (tx, rx) = mpsc::channel::<(PathBuf, StoredMap)>();
        let base = dir.join(CHECKPOINT);
        let journal = dir.join(JOURNAL);
        let tiles = dir.join(TILES);
        let shared = folded.clone();
        let thread = std::thread::Builder::new()
            .name("map-compactor".into())
            .spawn(move || {
                while let Ok((upto, map)) = rx.recv() {
                    let start = Instant::now();
                    let folded = compact(&map, &base, &journal, &tiles, &upto);
                    drop(map);
                    release_freed_memory();
                    match folded {
                        Ok(bytes) => {
                            shared.compactions.fetch_add(1, Ordering::Relaxed);
                            shared.base_bytes.fetch_add(bytes, Ordering::Relaxed);
                            let ms = start.elapsed().as_millis() as u64;
                            shared.last_ms.store(ms, Ordering::Relaxed);
                        }
                        Err(e) => {
                            eprintln!("folding the journal into the checkpoint failed: {e}");
                            shared.failures.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                }
            })
            .map_err(|source| StoreError::Io {
                path: dir.clone(),
                source,
            })?;
        let mut writer = JournalWriter::new(dir.join(JOURNAL));
        let mut found = segments(&dir.join(JOURNAL))?;
        // A header-only last segment (a crash right after opening it) is the writer's to
        // append to; the compactor folds only the segments before it.
        if let Some(last) = found.last() {
            let len = std::fs::metadata(last).map_err(|source| StoreError::Io {
                path: last.clone(),
                source,
            })?;
            if len.len() == HEADER_BYTES {
                writer.adopt(last.clone());
                found.pop();
            }
        }
        if let Some(last) = found.pop() {
            let _ = tx.send((last, map.stored()));
        }
        Ok(Self {
            writer,
            dir,
            every,
            compaction,
            empty,
            unsynced_bins: 0,
            journal_bytes: 0,
            paging: paging.filter(|_| every > 0),
            paged_in: Vec::new(),
            tile_counts: [0; 3],
            tile_failures: 0,
            failing: false,
            tx: Some(tx),
            thread: Some(thread),
            folded,
        })
    }

    /// The folder of the map's paged-out tiles.
    pub fn tiles_dir(&self) -> PathBuf {
        self.dir.join(TILES)
    }

    /// Reads back into `map` every tile on disk within the paging radius of `origin` (the
    /// next bin's), before the bin is fused; the next record names them. On an error the
    /// tiles read so far stay in and are recorded; the rest stay on disk.
    pub fn prepare(&mut self, map: &mut GlobalMap, origin: DVec3) -> Result<(), StoreError> {
        let Some(paging) = self.paging else {
            return Ok(());
        };
        let radius = paging
            .radius_m
            .max(f64::from(map.config().keep.max_range_m));
        for tile in map.paged_tiles_near(origin, radius) {
            self.page_in(map, tile)?;
        }
        Ok(())
    }

    /// Reads one paged-out tile back into the map and remembers it for the next record.
    fn page_in(&mut self, map: &mut GlobalMap, tile: TileKey) -> Result<(), StoreError> {
        let paged = map.page_in(&self.tiles_dir(), tile)?;
        self.paged_in.push(PageEvent::In(tile, paged));
        self.tile_counts[0] += 1;
        Ok(())
    }

    /// Writes the tiles the paging rule sends to disk (see the module doc) and drops them
    /// from `map`; the events, for the record. A tile that cannot be read in whole or
    /// written stays in memory and the paging stops there: the events so far are
    /// returned with the error, and the next bin tries again.
    fn page_out(&mut self, map: &mut GlobalMap) -> (Vec<PageEvent>, Option<StoreError>) {
        let mut events = Vec::new();
        let (Some(paging), Some(anchor)) = (self.paging, map.latest_origin()) else {
            return (events, None);
        };
        let config = *map.config();
        let side = config.tile_side();
        let keep = f64::from(config.keep.max_range_m).max(side);
        let resident = map.resident_tiles();
        let mut far: Vec<(f64, TileKey, u64)> = resident
            .iter()
            .map(|(t, n)| (tile_distance(*t, side, anchor), *t, *n))
            .filter(|(d, _, _)| *d > keep)
            .collect();
        far.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut in_memory = map.len() as u64;
        let room = (config.max_gaussians as u64 / 4) * 3;
        let version = map.increments();
        let dir = self.tiles_dir();
        for (distance, tile, count) in far {
            if distance <= paging.radius_m + side && in_memory <= room {
                break;
            }
            if map.paged_tiles().contains_key(&tile) {
                // Bins fused into a tile whose file is on disk (a keep range beyond the
                // paging radius): read it in so the tile goes out whole.
                if let Err(e) = self.page_in(map, tile) {
                    return (events, Some(e));
                }
                events.push(self.paged_in.pop().expect("page_in recorded it"));
            }
            let gaussians = map
                .take_tile(tile, version)
                .expect("a tile read back in is not paged out");
            if let Err(e) = write_tile(&dir, tile, version, &gaussians) {
                map.put_tile(tile, gaussians)
                    .expect("the tile was paged out just now");
                return (events, Some(e));
            }
            let paged = map.paged_tiles()[&tile];
            events.push(PageEvent::Out(tile, paged));
            in_memory -= count.min(in_memory);
            self.tile_counts[1] += 1;
            self.tile_counts[2] += paged.count;
        }
        (events, None)
    }

    /// Journals `inc`, which `map` has just taken in, with the tiles paged in before it
    /// ([`MapStore::prepare`]) and out after it, and makes it durable when due (see
    /// [`MapStore::new`]); closes the segment for the compactor when it is large enough.
    ///
    /// The record is kept whatever happens: on an error (a full disk, a failed sync, a
    /// base that cannot be written) it is not durable, and [`MapStore::flush`] (or the next
    /// record) writes it again. A tile that cannot be paged out stays in memory and is
    /// counted (`error/tile_write`); the record is written without it.
    ///
    /// While the store is [failing](MapStore::failing), the record is only kept: the write
    /// is left to the next [`MapStore::flush`], so a full disk costs one attempt per retry,
    /// not two per bin.
    pub fn record(&mut self, map: &mut GlobalMap, inc: &Increment) -> Result<Recorded, StoreError> {
        if self.every == 0 {
            return Ok(Recorded::NotKept);
        }
        self.keep(map, inc);
        match self.failing {
            true => Ok(Recorded::Kept),
            false => self.flush(map),
        }
    }

    /// Adds `inc`'s record to what the writer holds, paging tiles out first.
    fn keep(&mut self, map: &mut GlobalMap, inc: &Increment) {
        let (after, paging) = self.page_out(map);
        if let Some(e) = paging {
            eprintln!("paging a tile out failed (it stays in memory): {e}");
            self.tile_failures += 1;
        }
        let before = std::mem::take(&mut self.paged_in);
        self.journal_bytes += self.writer.push(map, inc, &before, &after);
        self.unsynced_bins += 1;
    }

    /// Writes what is kept and not yet on disk (the first base, records whose write or sync
    /// failed) and syncs when due; `map` must be the map after the last record kept.
    /// [`Recorded::Durable`] once every record so far is durable.
    pub fn flush(&mut self, map: &GlobalMap) -> Result<Recorded, StoreError> {
        let flushed = self.try_flush(map);
        self.failing = flushed.is_err();
        flushed
    }

    fn try_flush(&mut self, map: &GlobalMap) -> Result<Recorded, StoreError> {
        if self.every == 0 {
            return Ok(Recorded::NotKept);
        }
        // The base comes first: records without their base would not restore.
        if let Some(empty) = &self.empty {
            checkpoint(empty, &self.dir)?;
            self.empty = None;
        }
        if self.unsynced_bins < self.every {
            self.writer.write()?;
            return Ok(Recorded::Written);
        }
        self.writer.sync()?;
        self.unsynced_bins = 0;
        let base_bytes = map.stored_bytes();
        if self.writer.segment_bytes() >= self.compaction.min_bytes.max(base_bytes) {
            if let (Some(path), Some(tx)) = (self.writer.close_segment()?, &self.tx) {
                let _ = tx.send((path, map.stored()));
            }
        }
        Ok(Recorded::Durable)
    }

    /// Whether the last record or flush failed: records are kept that are not yet where
    /// they should be, and [`MapStore::flush`] is to be tried again.
    pub fn failing(&self) -> bool {
        self.failing
    }

    /// The store's counters: tiles that could not be paged out, bytes journaled, base
    /// rewrites, bytes they wrote, failures, the last one's duration, tiles paged in and
    /// out, and the Gaussians paged out.
    pub fn counts(&self) -> [(&'static str, u64); 9] {
        let f = &self.folded;
        [
            ("error/tile_write", self.tile_failures),
            ("map/tiles_paged_in", self.tile_counts[0]),
            ("map/tiles_paged_out", self.tile_counts[1]),
            ("map/gaussians_paged_out", self.tile_counts[2]),
            ("map/journal_bytes", self.journal_bytes),
            ("map/compactions", f.compactions.load(Ordering::Relaxed)),
            ("map/compacted_bytes", f.base_bytes.load(Ordering::Relaxed)),
            ("error/compaction", f.failures.load(Ordering::Relaxed)),
            ("map/compaction_ms", f.last_ms.load(Ordering::Relaxed)),
        ]
    }

    /// Syncs the journal and waits for the compactor to finish what it was given, so the
    /// node can save the whole map as the base ([`super::map_files::export`]).
    pub fn finish(&mut self) -> Result<(), StoreError> {
        let synced = self.writer.close_segment().map(|_| ());
        self.tx = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        synced
    }
}

impl Drop for MapStore {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

/// Writes `map` (the map after the record that ends the segment `upto`) as the base
/// atomically, then removes the segments of `journal` up to `upto` (inclusive), which it
/// holds, and the tile files no later record can name. Returns the base's size in bytes.
fn compact(
    map: &StoredMap,
    base: &Path,
    journal: &Path,
    tiles: &Path,
    upto: &Path,
) -> Result<u64, StoreError> {
    let bytes = map.save(base)?;
    for path in segments(journal)?.iter().filter(|p| p.as_path() <= upto) {
        std::fs::remove_file(path).map_err(|source| StoreError::Io {
            path: path.clone(),
            source,
        })?;
    }
    collect_garbage(tiles, map.paged_tiles(), map.increments())?;
    Ok(bytes)
}
