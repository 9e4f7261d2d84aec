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
//! journal. The compactor loads the base from disk, replays the closed segments, writes the
//! base atomically and only then removes the segments, so a crash at any point leaves a
//! base and segments that restore every published bin ([`super::map_files::restore`]). While
//! it works, the base's copy in memory adds to the node's resident size.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::Instant;

use crate::fusion::{segments, AtTornTail, GlobalMap, Increment, JournalWriter, StoreError};

use super::map_files::{checkpoint, CHECKPOINT, JOURNAL};

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
    tx: Option<mpsc::Sender<PathBuf>>,
    thread: Option<JoinHandle<()>>,
    folded: Arc<Folded>,
}

impl MapStore {
    /// A store in `dir` for `map` (new or resumed), syncing the journal after every `every`
    /// bins (0: nothing is written while running; the node saves the map when it stops).
    /// Segments a previous run left (after a crash) are handed to the compactor at once.
    pub fn new(
        dir: PathBuf,
        map: &GlobalMap,
        every: u64,
        compaction: Compaction,
    ) -> Result<Self, StoreError> {
        let empty = match dir.join(CHECKPOINT).exists() {
            true => None,
            false => Some(GlobalMap::new(*map.config()).expect("a map's settings are valid")),
        };
        let folded = Arc::<Folded>::default();
        let (tx, rx) = mpsc::channel::<PathBuf>();
        let base = dir.join(CHECKPOINT);
        let journal = dir.join(JOURNAL);
        let shared = folded.clone();
        let thread = std::thread::Builder::new()
            .name("map-compactor".into())
            .spawn(move || {
                while let Ok(upto) = rx.recv() {
                    let start = Instant::now();
                    match compact(&base, &journal, &upto) {
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
        if let Some(last) = segments(&dir.join(JOURNAL))?.pop() {
            let _ = tx.send(last);
        }
        Ok(Self {
            writer: JournalWriter::new(dir.join(JOURNAL)),
            dir,
            every,
            compaction,
            empty,
            unsynced_bins: 0,
            journal_bytes: 0,
            tx: Some(tx),
            thread: Some(thread),
            folded,
        })
    }

    /// Journals `inc`, which `map` has just taken in, and makes it durable when due (see
    /// [`MapStore::new`]); closes the segment for the compactor when it is large enough.
    /// Returns whether the record is durable.
    pub fn record(&mut self, map: &GlobalMap, inc: &Increment) -> Result<bool, StoreError> {
        if self.every == 0 {
            return Ok(false);
        }
        if let Some(empty) = self.empty.take() {
            checkpoint(&empty, &self.dir)?;
        }
        self.journal_bytes += self.writer.append(map, inc)?;
        self.unsynced_bins += 1;
        if self.unsynced_bins < self.every {
            return Ok(false);
        }
        self.writer.sync()?;
        self.unsynced_bins = 0;
        let base_bytes = map.stored_bytes();
        if self.writer.segment_bytes() >= self.compaction.min_bytes.max(base_bytes) {
            if let (Some(path), Some(tx)) = (self.writer.close_segment()?, &self.tx) {
                let _ = tx.send(path);
            }
        }
        Ok(true)
    }

    /// The store's counters: bytes journaled, base rewrites, bytes they wrote, failures and
    /// the last one's duration.
    pub fn counts(&self) -> [(&'static str, u64); 5] {
        let f = &self.folded;
        [
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

/// Folds the segments of `journal` up to `upto` (inclusive) into the base: loads it,
/// replays them, saves it atomically, then removes them. Returns the base's size in bytes.
fn compact(base: &Path, journal: &Path, upto: &Path) -> Result<u64, StoreError> {
    let mut map = GlobalMap::load(base)?;
    let folded: Vec<PathBuf> = segments(journal)?
        .into_iter()
        .filter(|p| p.as_path() <= upto)
        .collect();
    map.replay_journal(&folded, AtTornTail::Fail)?;
    let bytes = map.to_bytes();
    renderer::atomic::write_bytes_atomic(base, &bytes).map_err(|source| StoreError::Io {
        path: base.to_path_buf(),
        source,
    })?;
    for path in &folded {
        std::fs::remove_file(path).map_err(|source| StoreError::Io {
            path: path.clone(),
            source,
        })?;
    }
    Ok(bytes.len() as u64)
}
