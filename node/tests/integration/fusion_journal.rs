//! The global map's journal: a base file plus the records of what each bin changed restore
//! the map bit for bit, whenever a crash stops the node (between a record and the base's
//! rewrite, during the rewrite, in the middle of a record); a torn last record is cut and
//! said; damage anywhere else is a typed error; the background compactor keeps the bytes
//! written within the bytes journaled, and the copy of the map it writes stays the map as it
//! was when taken while the map goes on changing.
//!
//! The crashes here are simulated on the files (the states a crash can leave); a real
//! SIGKILL of a running node is in `node_crash.rs`.

use std::path::{Path, PathBuf};

use glam::{DAffine3, DVec3};
use node::fusion::{segments, AtTornTail, GlobalMap, JournalWriter, StoreError};
use node::store::map_files::{restore, CHECKPOINT, JOURNAL};
use node::store::map_store::{MapStore, Recorded};
use node::store::Compaction;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::fusion::{map_with, random_bin};

/// A fresh folder for test `name`, under the system temporary folder.
pub(crate) fn scratch(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("stereosplat_journal_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The map restored from `dir`, which must hold one.
fn restored(dir: &Path) -> GlobalMap {
    restore(dir, AtTornTail::Cut)
        .unwrap()
        .expect("a checkpoint")
        .map
}

/// Fuses `bins` random bins (budget 300, so cells are replaced and evicted; every 17th bin
/// empty; the last one 1,000 km out) into a new map whose empty base is saved in `dir`,
/// journaling each; the map after every bin, as file bytes.
fn journaled_drive(dir: &Path, bins: u64, writer: &mut JournalWriter) -> Vec<Vec<u8>> {
    let mut map = map_with(1.0, 0.1, 300);
    map.save(dir.join(CHECKPOINT)).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut states = Vec::new();
    for k in 0..bins {
        let (set, mut pose) = random_bin(&mut rng, k);
        if k + 1 == bins {
            pose = DAffine3::from_translation(DVec3::new(1.0e6, -2.0e5, 3.0)) * pose;
        }
        let inc = map.insert_bin(k, &set, pose).unwrap();
        writer.append(&map, &inc, &[], &[]).unwrap();
        writer.sync().unwrap();
        states.push(map.to_bytes());
    }
    states
}

#[test]
fn a_base_and_its_journal_restore_the_map_bit_for_bit_after_every_bin() {
    let dir = scratch("every_bin");
    let mut map = map_with(1.0, 0.1, 300);
    map.save(dir.join(CHECKPOINT)).unwrap();
    let mut writer = JournalWriter::new(dir.join(JOURNAL));
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut evicted, mut replaced) = (0, 0);
    for k in 0..60u64 {
        let (set, pose) = random_bin(&mut rng, k);
        let inc = map.insert_bin(k, &set, pose).unwrap();
        (evicted, replaced) = (evicted + inc.stats.evicted, replaced + inc.stats.replaced);
        writer.append(&map, &inc, &[], &[]).unwrap();
        writer.sync().unwrap();
        // A crash here (after the record, before any compaction) restores this map.
        assert_eq!(restored(&dir).to_bytes(), map.to_bytes(), "bin {k}");
        if k % 20 == 19 {
            writer.close_segment().unwrap();
        }
    }
    assert!(
        evicted > 0 && replaced > 0,
        "{evicted} evicted, {replaced} replaced"
    );
    assert_eq!(segments(&dir.join(JOURNAL)).unwrap().len(), 3);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_crash_during_compaction_restores_every_bin() {
    let dir = scratch("compaction");
    let mut writer = JournalWriter::new(dir.join(JOURNAL));
    let states = journaled_drive(&dir, 30, &mut writer);
    let last = states.last().unwrap();
    let base = dir.join(CHECKPOINT);
    // Killed while writing the new base: the temporary sibling is left, the old base whole.
    std::fs::write(
        dir.join("global_map.ssgmap.999-1.tmp"),
        &last[..last.len() / 2],
    )
    .unwrap();
    assert_eq!(&restored(&dir).to_bytes(), last);
    // Killed after the new base (through bin 19) replaced the old, before its segments went:
    // the records it holds are skipped.
    std::fs::write(&base, &states[19]).unwrap();
    let r = restore(&dir, AtTornTail::Cut).unwrap().unwrap();
    assert_eq!((r.replay.applied, r.replay.skipped), (10, 20));
    assert_eq!(&r.map.to_bytes(), last);
    // The base holds everything: nothing to replay.
    std::fs::write(&base, last).unwrap();
    assert_eq!(
        restore(&dir, AtTornTail::Cut)
            .unwrap()
            .unwrap()
            .replay
            .applied,
        0
    );
    assert_eq!(&restored(&dir).to_bytes(), last);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_torn_last_record_is_cut_and_said_and_the_complete_ones_kept() {
    let dir = scratch("torn");
    let mut writer = JournalWriter::new(dir.join(JOURNAL));
    let states = journaled_drive(&dir, 12, &mut writer);
    let segment = segments(&dir.join(JOURNAL)).unwrap().pop().unwrap();
    let whole = std::fs::read(&segment).unwrap();
    // The last record loses its last 7 bytes (checksum cut off).
    std::fs::write(&segment, &whole[..whole.len() - 7]).unwrap();
    // A reader stops before it and leaves the file; the compactor refuses it.
    let read = restore(&dir, AtTornTail::Stop).unwrap().unwrap();
    assert_eq!(read.map.to_bytes(), states[10]);
    assert!(read.replay.torn.is_some());
    let len = std::fs::metadata(&segment).unwrap().len();
    assert_eq!(len, whole.len() as u64 - 7);
    assert!(restore(&dir, AtTornTail::Fail).is_err());
    let r = restore(&dir, AtTornTail::Cut).unwrap().unwrap();
    assert_eq!(r.replay.applied, 11);
    let torn = r.replay.torn.clone().expect("the cut is reported");
    assert_eq!(torn.path, segment);
    assert_eq!(torn.kept_bytes + torn.cut_bytes, whole.len() as u64 - 7);
    assert!(torn.cut_bytes > 7, "{torn:?}");
    assert_eq!(r.map.to_bytes(), states[10]);
    // The file was cut to its complete records: a second restore finds nothing torn.
    assert_eq!(std::fs::metadata(&segment).unwrap().len(), torn.kept_bytes);
    let again = restore(&dir, AtTornTail::Cut).unwrap().unwrap();
    assert_eq!((again.replay.applied, again.replay.torn), (11, None));
    // Half a record of garbage after complete ones (a length that runs past the end, then
    // a checksum that does not match) is cut the same way.
    for tail in [
        vec![0xff_u8; 9],
        [&40u32.to_le_bytes()[..], &[7u8; 52]].concat(),
    ] {
        let mut bytes = std::fs::read(&segment).unwrap();
        let kept = bytes.len() as u64;
        bytes.extend_from_slice(&tail);
        std::fs::write(&segment, &bytes).unwrap();
        let r = restore(&dir, AtTornTail::Cut).unwrap().unwrap();
        let torn = r.replay.torn.unwrap();
        assert_eq!((torn.kept_bytes, torn.cut_bytes), (kept, tail.len() as u64));
        assert_eq!(r.map.to_bytes(), states[10]);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn damage_before_the_journal_s_end_and_a_journal_without_base_are_typed_errors() {
    let dir = scratch("damaged");
    let mut writer = JournalWriter::new(dir.join(JOURNAL));
    journaled_drive(&dir, 6, &mut writer);
    writer.close_segment().unwrap();
    let mut more = restored(&dir);
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let (set, pose) = random_bin(&mut rng, 6);
    let inc = more.insert_bin(6, &set, pose).unwrap();
    writer.append(&more, &inc, &[], &[]).unwrap();
    writer.sync().unwrap();
    let journal = segments(&dir.join(JOURNAL)).unwrap();
    assert_eq!(journal.len(), 2);
    // A flipped byte in the older segment: the journal is damaged, not torn.
    let mut bytes = std::fs::read(&journal[0]).unwrap();
    let at = bytes.len() - 20;
    bytes[at] ^= 0x40;
    std::fs::write(&journal[0], &bytes).unwrap();
    let e = restore(&dir, AtTornTail::Cut).unwrap_err();
    assert!(
        matches!(&e, StoreError::Invalid { path, what, .. } if *path == journal[0] && what.contains("corrupt")),
        "{e}"
    );
    bytes[at] ^= 0x40;
    std::fs::write(&journal[0], &bytes).unwrap();
    assert_eq!(restored(&dir).to_bytes(), more.to_bytes());
    // A missing record (the older segment gone): a gap in the sequence.
    std::fs::rename(&journal[0], dir.join("aside")).unwrap();
    let e = restore(&dir, AtTornTail::Cut).unwrap_err();
    assert!(e.to_string().contains("out of sequence"), "{e}");
    std::fs::rename(dir.join("aside"), &journal[0]).unwrap();
    // Segments without the base they extend.
    std::fs::remove_file(dir.join(CHECKPOINT)).unwrap();
    let e = restore(&dir, AtTornTail::Cut).unwrap_err();
    assert!(e.to_string().contains("without its base"), "{e}");
    // A segment from another program.
    std::fs::write(&journal[0], b"not a journal at all").unwrap();
    map_with(1.0, 0.1, 300).save(dir.join(CHECKPOINT)).unwrap();
    assert!(matches!(
        restore(&dir, AtTornTail::Cut),
        Err(StoreError::BadMagic { .. })
    ));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_compactor_folds_the_journal_into_the_base_within_the_bytes_journaled() {
    let dir = scratch("compactor");
    let mut map = map_with(1.0, 0.1, 100_000);
    let compaction = Compaction { min_bytes: 0 };
    let mut store = MapStore::new(dir.clone(), &map, 1, compaction, None).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut increments = 0u64;
    for k in 0..200u64 {
        let (set, pose) = random_bin(&mut rng, k);
        let inc = map.insert_bin(k, &set, pose).unwrap();
        increments += (inc.added.len() * 88 + inc.removed.len() * 8) as u64;
        assert_eq!(
            store.record(&mut map, &inc).unwrap(),
            Recorded::Durable,
            "synced before publishing"
        );
    }
    store.finish().unwrap();
    let counts: std::collections::BTreeMap<_, _> = store.counts().into_iter().collect();
    let (journal, compacted) = (counts["map/journal_bytes"], counts["map/compacted_bytes"]);
    eprintln!("{increments} bytes of increments, {journal} journaled, {compacted} rewritten as the base, {} compactions", counts["map/compactions"]);
    assert_eq!(counts["error/compaction"], 0);
    assert!(counts["map/compactions"] >= 2, "{counts:?}");
    // Each rewrite waited for as many journal bytes as the base it wrote.
    assert!(compacted <= journal, "{compacted} > {journal}");
    assert!(
        journal <= increments + 200 * 120,
        "{journal} for {increments}"
    );
    assert!(segments(&dir.join(JOURNAL)).unwrap().len() <= 2);
    assert_eq!(restored(&dir).to_bytes(), map.to_bytes());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_compactor_s_copy_writes_the_map_as_it_was_however_the_map_changes_after() {
    let dir = scratch("stored_copy");
    let mut map = map_with(1.0, 0.1, 300);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for k in 0..20u64 {
        let (set, pose) = random_bin(&mut rng, k);
        map.insert_bin(k, &set, pose).unwrap();
    }
    let before = map.to_bytes();
    let copy = map.stored();
    assert_eq!(copy.stored_bytes(), map.stored_bytes());
    // Replaced cells, evictions (budget 300) and new ids after the copy was taken.
    let (mut evicted, mut replaced) = (0, 0);
    for k in 20..40u64 {
        let (set, pose) = random_bin(&mut rng, k);
        let inc = map.insert_bin(k, &set, pose).unwrap();
        (evicted, replaced) = (evicted + inc.stats.evicted, replaced + inc.stats.replaced);
    }
    assert!(
        evicted > 0 && replaced > 0,
        "{evicted} evicted, {replaced} replaced"
    );
    assert_ne!(map.to_bytes(), before);
    assert_eq!(copy.to_bytes(), before);
    assert_eq!(copy.increments(), 20);
    let path = dir.join(CHECKPOINT);
    copy.save(&path).unwrap();
    assert_eq!(GlobalMap::load(&path).unwrap().to_bytes(), before);
    // The map itself still saves and restores as it now is.
    map.save(&path).unwrap();
    assert_eq!(GlobalMap::load(&path).unwrap().to_bytes(), map.to_bytes());
    let _ = std::fs::remove_dir_all(&dir);
}
