//! The journal under failing writes: a full disk in the middle of a record, a failed fsync,
//! a file that cannot be cut back. Whatever fails, a restore (as after a crash at that
//! moment) gives every record that was reported durable and nothing else, the records
//! kept in memory are written again once the disk takes them, and no synced record is ever
//! cut. Damage that a failed write cannot explain (records lost between two others) is a
//! typed error that leaves the files as they are.
//!
//! The failures come from a test double of the segment file (`Faulty`: a real file whose
//! writes stop where a full disk would stop them, and whose fsync or truncation fails on
//! demand), since a real device's failed fsync cannot be produced here; a real full disk (a
//! small tmpfs, mounted as root) refuses the first base here and fills mid-drive in
//! `node_disk_full.rs`.

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use node::fusion::{
    segments, AtTornTail, GlobalMap, JournalWriter, SegmentFile, StoreError, JOURNAL_HEADER_BYTES,
};
use node::store::map_files::{restore, CHECKPOINT, JOURNAL};
use node::store::map_store::{MapStore, Recorded};
use node::store::Compaction;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::fusion::{map_with, random_bin};
use super::fusion_journal::scratch;
use super::node_disk_full::{fill, Tmpfs};

/// What the disk does with the next operations.
#[derive(Debug, Default)]
struct Plan {
    /// Bytes the disk still takes (`None`: as many as asked); a write past it writes what
    /// fits, then fails as a full disk does.
    room: Option<u64>,
    /// Syncs to fail (an I/O error) before they succeed again.
    failing_syncs: u32,
    /// Truncation fails.
    no_cut: bool,
}

/// A real segment file whose operations fail as [`Plan`] says.
struct Faulty {
    file: File,
    plan: Arc<Mutex<Plan>>,
}

impl SegmentFile for Faulty {
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        let mut plan = self.plan.lock().unwrap();
        if let Some(room) = plan.room {
            if bytes.len() as u64 > room {
                std::io::Write::write_all(&mut self.file, &bytes[..room as usize])?;
                plan.room = Some(0);
                return Err(std::io::Error::from_raw_os_error(28)); // ENOSPC
            }
            plan.room = Some(room - bytes.len() as u64);
        }
        std::io::Write::write_all(&mut self.file, bytes)
    }

    fn sync_data(&mut self) -> std::io::Result<()> {
        let mut plan = self.plan.lock().unwrap();
        if plan.failing_syncs > 0 {
            plan.failing_syncs -= 1;
            return Err(std::io::Error::from_raw_os_error(5)); // EIO
        }
        self.file.sync_data()
    }

    fn set_len(&mut self, len: u64) -> std::io::Result<()> {
        if self.plan.lock().unwrap().no_cut {
            return Err(std::io::Error::from_raw_os_error(5));
        }
        self.file.set_len(len)
    }
}

/// A writer into `dir`'s journal whose files follow `plan`.
fn faulty_writer(dir: &Path, plan: &Arc<Mutex<Plan>>) -> JournalWriter {
    let plan = plan.clone();
    JournalWriter::with_files(
        dir.join(JOURNAL),
        Box::new(move |path: &Path, reuse: bool| {
            let mut options = OpenOptions::new();
            options.write(true);
            match reuse {
                true => options.truncate(true),
                false => options.create_new(true),
            };
            let file = options.open(path)?;
            Ok(Box::new(Faulty {
                file,
                plan: plan.clone(),
            }) as Box<dyn SegmentFile>)
        }),
    )
}

/// A drive of random bins into a new map whose empty base is saved in `dir`.
struct Drive {
    map: GlobalMap,
    rng: ChaCha8Rng,
    next: u64,
}

impl Drive {
    fn new(dir: &Path) -> Self {
        let map = map_with(1.0, 0.1, 300);
        map.save(dir.join(CHECKPOINT)).unwrap();
        Self {
            map,
            rng: ChaCha8Rng::seed_from_u64(3),
            next: 0,
        }
    }

    /// Fuses the next bin and appends its record; the append's result.
    fn bin(&mut self, writer: &mut JournalWriter) -> Result<u64, StoreError> {
        let (set, pose) = random_bin(&mut self.rng, self.next);
        let inc = self.map.insert_bin(self.next, &set, pose).unwrap();
        self.next += 1;
        writer.append(&self.map, &inc, &[], &[])
    }
}

/// A faulty writer (no faults planned yet) into `dir` after three bins, each synced; the
/// plan, the writer, the drive and the segment holding the three records.
fn three_synced_bins(dir: &Path) -> (Arc<Mutex<Plan>>, JournalWriter, Drive, PathBuf) {
    let plan = Arc::new(Mutex::new(Plan::default()));
    let mut writer = faulty_writer(dir, &plan);
    let mut drive = Drive::new(dir);
    for _ in 0..3 {
        drive.bin(&mut writer).unwrap();
        writer.sync().unwrap();
    }
    let first = segments(&dir.join(JOURNAL)).unwrap().pop().unwrap();
    (plan, writer, drive, first)
}

/// The map a crash now would leave (the files read as they are).
fn after_crash(dir: &Path) -> GlobalMap {
    restore(dir, AtTornTail::Stop).unwrap().unwrap().map
}

fn len(path: &Path) -> u64 {
    std::fs::metadata(path).unwrap().len()
}

#[test]
fn a_full_disk_mid_record_cuts_it_back_and_the_retry_writes_every_record() {
    let dir = scratch("full");
    let (plan, mut writer, mut drive, first) = three_synced_bins(&dir);
    drive.bin(&mut writer).unwrap();
    writer.sync().unwrap();
    let durable = drive.map.to_bytes();
    let synced_len = len(&first);
    // The disk fills 100 bytes into the fifth record.
    plan.lock().unwrap().room = Some(100);
    let e = drive.bin(&mut writer).unwrap_err();
    assert!(e.to_string().contains("No space left"), "{e}");
    assert_eq!(len(&first), synced_len, "the partial record is cut back");
    assert_eq!(after_crash(&dir).to_bytes(), durable);
    // A sixth bin while the disk is still full: its record is kept too; the new segment
    // it would go to cannot even take its header.
    let e = drive.bin(&mut writer).unwrap_err();
    assert!(e.to_string().contains("No space left"), "{e}");
    assert_eq!(writer.unsynced_records(), 2);
    assert_eq!(after_crash(&dir).to_bytes(), durable);
    // Room again: one sync writes both kept records, into the segment it had begun.
    plan.lock().unwrap().room = None;
    writer.sync().unwrap();
    assert_eq!(writer.unsynced_records(), 0);
    let found = segments(&dir.join(JOURNAL)).unwrap();
    assert_eq!(found.len(), 2, "{found:?}");
    let restored = restore(&dir, AtTornTail::Cut).unwrap().unwrap();
    assert_eq!(restored.map.to_bytes(), drive.map.to_bytes());
    assert_eq!((restored.replay.applied, restored.replay.torn), (6, None));
    assert!(restored.replay.failed_writes.is_empty());
    for _ in 0..3 {
        drive.bin(&mut writer).unwrap();
        writer.sync().unwrap();
    }
    assert_eq!(after_crash(&dir).to_bytes(), drive.map.to_bytes());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_failed_fsync_is_not_taken_for_success_and_its_records_go_to_a_new_segment() {
    let dir = scratch("fsync");
    let (plan, mut writer, mut drive, first) = three_synced_bins(&dir);
    let synced_len = len(&first);
    drive.bin(&mut writer).unwrap();
    plan.lock().unwrap().failing_syncs = 1;
    assert!(writer.sync().is_err());
    // The record after the last good sync is not trusted to the old file: it is cut from
    // it and kept; the next sync writes it to a new segment and syncs that.
    assert_eq!(len(&first), synced_len);
    assert_eq!(writer.unsynced_records(), 1);
    writer.sync().unwrap();
    let found = segments(&dir.join(JOURNAL)).unwrap();
    assert_eq!(found.len(), 2);
    assert!(len(&found[1]) > JOURNAL_HEADER_BYTES);
    let restored = restore(&dir, AtTornTail::Cut).unwrap().unwrap();
    assert_eq!(restored.map.to_bytes(), drive.map.to_bytes());
    assert_eq!(restored.replay.applied, 4);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_failed_write_that_cannot_be_cut_back_is_skipped_at_restore_and_nothing_is_cut() {
    let dir = scratch("no_cut");
    let (plan, mut writer, mut drive, first) = three_synced_bins(&dir);
    let synced_len = len(&first);
    *plan.lock().unwrap() = Plan {
        room: Some(60),
        failing_syncs: 0,
        no_cut: true,
    };
    assert!(drive.bin(&mut writer).is_err());
    assert_eq!(len(&first), synced_len + 60, "the partial record stays");
    *plan.lock().unwrap() = Plan::default();
    drive.bin(&mut writer).unwrap();
    writer.sync().unwrap();
    let restored = restore(&dir, AtTornTail::Cut).unwrap().unwrap();
    assert_eq!(restored.map.to_bytes(), drive.map.to_bytes());
    assert_eq!(restored.replay.torn, None);
    let skipped = &restored.replay.failed_writes;
    assert_eq!(skipped.len(), 1, "{skipped:?}");
    assert_eq!(
        (&skipped[0].path, skipped[0].offset, skipped[0].bytes),
        (&first, synced_len, 60)
    );
    assert_eq!(
        len(&first),
        synced_len + 60,
        "a restore cuts nothing before the end"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The records of a one-segment journal, each with its length and checksum.
fn records(segment: &Path) -> Vec<Vec<u8>> {
    let bytes = std::fs::read(segment).unwrap();
    let mut at = JOURNAL_HEADER_BYTES as usize;
    let mut out = Vec::new();
    while at < bytes.len() {
        let len = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        out.push(bytes[at..at + 12 + len].to_vec());
        at += 12 + len;
    }
    out
}

#[test]
fn a_partial_record_before_its_copy_is_skipped_and_one_before_later_records_is_refused() {
    let dir = scratch("partial");
    let mut writer = JournalWriter::new(dir.join(JOURNAL));
    let mut drive = Drive::new(&dir);
    for _ in 0..4 {
        drive.bin(&mut writer).unwrap();
    }
    writer.sync().unwrap();
    let segment = segments(&dir.join(JOURNAL)).unwrap().pop().unwrap();
    let whole = std::fs::read(&segment).unwrap();
    let recs = records(&segment);
    assert_eq!(recs.len(), 4);
    let header = &whole[..JOURNAL_HEADER_BYTES as usize];
    let partial = &recs[2][..50];
    // A write of record 3 that stopped after 50 bytes, then record 3 again and record 4.
    let redone = [header, &recs[0], &recs[1], partial, &recs[2], &recs[3]].concat();
    std::fs::write(&segment, &redone).unwrap();
    let r = restore(&dir, AtTornTail::Cut).unwrap().unwrap();
    assert_eq!(r.map.to_bytes(), drive.map.to_bytes());
    assert_eq!(r.replay.failed_writes.len(), 1);
    assert_eq!(r.replay.failed_writes[0].bytes, 50);
    assert_eq!(len(&segment), redone.len() as u64);
    // The same partial record followed by record 4 alone: record 3 is lost, which no
    // failed write of this writer leaves. An error, and the file is left as it is.
    let gap = [header, &recs[0], &recs[1], partial, &recs[3]].concat();
    std::fs::write(&segment, &gap).unwrap();
    let e = restore(&dir, AtTornTail::Cut).unwrap_err();
    assert!(e.to_string().contains("later records"), "{e}");
    assert_eq!(len(&segment), gap.len() as u64);
    // A flipped byte inside record 2, which records 3 and 4 follow: damage, not a tail.
    let mut flipped = whole.clone();
    let inside = JOURNAL_HEADER_BYTES as usize + recs[0].len() + 30;
    flipped[inside] ^= 0x10;
    std::fs::write(&segment, &flipped).unwrap();
    assert!(restore(&dir, AtTornTail::Cut).is_err());
    assert_eq!(len(&segment), whole.len() as u64);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_header_only_last_segment_is_kept_and_appended_to_while_the_compactor_folds_the_rest() {
    let dir = scratch("header_only");
    let mut writer = JournalWriter::new(dir.join(JOURNAL));
    let mut drive = Drive::new(&dir);
    for _ in 0..3 {
        drive.bin(&mut writer).unwrap();
    }
    writer.sync().unwrap();
    let first = segments(&dir.join(JOURNAL)).unwrap().pop().unwrap();
    // A crash right after the next segment was opened: its header, no record.
    let header = std::fs::read(&first).unwrap()[..JOURNAL_HEADER_BYTES as usize].to_vec();
    let opened = node::fusion::segment_path(&dir.join(JOURNAL), drive.map.increments() + 1);
    std::fs::write(&opened, &header).unwrap();
    let mut map = restore(&dir, AtTornTail::Cut).unwrap().unwrap().map;
    assert_eq!(map.to_bytes(), drive.map.to_bytes());
    let mut store = MapStore::new(dir.clone(), &map, 1, Compaction::default(), None).unwrap();
    let (set, pose) = random_bin(&mut drive.rng, 3);
    let inc = map.insert_bin(3, &set, pose).unwrap();
    assert_eq!(store.record(&mut map, &inc).unwrap(), Recorded::Durable);
    store.finish().unwrap();
    // The compactor folded the first segment into the base; the adopted one holds the
    // new record.
    let found = segments(&dir.join(JOURNAL)).unwrap();
    assert_eq!(found, vec![opened.clone()]);
    assert!(len(&opened) > JOURNAL_HEADER_BYTES);
    assert_eq!(
        restore(&dir, AtTornTail::Fail)
            .unwrap()
            .unwrap()
            .map
            .to_bytes(),
        map.to_bytes()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_segment_name_taken_by_another_file_is_a_clear_error_not_a_truncation() {
    let dir = scratch("taken");
    let mut writer = JournalWriter::new(dir.join(JOURNAL));
    let mut drive = Drive::new(&dir);
    std::fs::create_dir_all(dir.join(JOURNAL)).unwrap();
    let taken = node::fusion::segment_path(&dir.join(JOURNAL), 1);
    std::fs::write(&taken, b"someone else's").unwrap();
    let e = drive.bin(&mut writer).unwrap_err();
    assert!(e.to_string().contains("already exists"), "{e}");
    assert_eq!(std::fs::read(&taken).unwrap(), b"someone else's");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_first_base_that_cannot_be_written_is_retried_and_no_record_goes_before_it() {
    let root = scratch("first_base");
    // A real full disk (a tmpfs filled to the last byte) refuses the first base.
    let disk = Tmpfs::mount(root.join("disk"), "1m");
    let (ballast, _) = fill(&disk.0);
    let dir = disk.0.clone();
    let mut map = map_with(1.0, 0.1, 300);
    let mut store = MapStore::new(dir.clone(), &map, 1, Compaction::default(), None).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (set, pose) = random_bin(&mut rng, 0);
    let inc = map.insert_bin(0, &set, pose).unwrap();
    let e = store.record(&mut map, &inc).unwrap_err();
    assert!(e.to_string().contains("No space left"), "{e}");
    assert!(store.failing());
    assert!(store.flush(&map).is_err(), "still full");
    // A bin fused while the store fails is kept, not written: the next flush writes it.
    let (set, pose) = random_bin(&mut rng, 1);
    let inc = map.insert_bin(1, &set, pose).unwrap();
    assert_eq!(store.record(&mut map, &inc).unwrap(), Recorded::Kept);
    assert!(
        segments(&dir.join(JOURNAL)).unwrap().is_empty(),
        "no record before its base"
    );
    std::fs::remove_file(&ballast).unwrap();
    assert_eq!(store.flush(&map).unwrap(), Recorded::Durable);
    assert!(!store.failing());
    let (set, pose) = random_bin(&mut rng, 2);
    let inc = map.insert_bin(2, &set, pose).unwrap();
    assert_eq!(store.record(&mut map, &inc).unwrap(), Recorded::Durable);
    store.finish().unwrap();
    let restored = restore(&dir, AtTornTail::Fail).unwrap().unwrap();
    assert_eq!(restored.map.to_bytes(), map.to_bytes());
    drop(disk);
    let _ = std::fs::remove_dir_all(&root);
}
