//! What the node says on stderr as it starts its map: the checkpoint it resumed, the
//! journal records it replayed past the base, the failed writes it skipped, a torn record it
//! cut, the fusion settings asked for that the resumed map does not take, and an old map
//! moved aside for a fresh one.

use crate::store::map_files::Start;

/// Says on stderr how the node's map was started ([`Start`]).
pub(super) fn announce_start(start: &Start) {
    if let Some(path) = &start.resumed_from {
        let m = &start.map;
        eprintln!(
            "resumed the global map of {}: {} Gaussians, bins up to {:?}, sequence {}, epoch {}",
            path.display(),
            m.len(),
            m.last_bin_id(),
            m.increments(),
            m.epoch()
        );
    }
    if let Some(replay) = &start.replay {
        eprintln!(
            "replayed {} journal records past the base ({} it already held)",
            replay.applied, replay.skipped
        );
        for w in &replay.failed_writes {
            eprintln!(
                "skipped {} bytes of a journal write that failed at byte {} of {} (its records follow it again)",
                w.bytes,
                w.offset,
                w.path.display()
            );
        }
        if let Some(t) = &replay.torn {
            eprintln!(
                "cut a record torn by a crash at the end of {}: kept its first {} bytes, cut {}",
                t.path.display(),
                t.kept_bytes,
                t.cut_bytes
            );
        }
    }
    for to in &start.moved_aside {
        eprintln!(
            "starting a fresh global map; the old one is kept as {}",
            to.display()
        );
    }
    for kept in &start.settings_kept {
        eprintln!(
            "warning: the resumed map keeps its {} of {}, not the {} asked for (--fresh starts a map with it)",
            kept.flag, kept.stored, kept.asked
        );
    }
}
