//! The node's global-map files under its out folder: the checkpoint it keeps as bins are
//! fused and resumes from when it starts again, and the exports it writes when it stops.
//!
//! The checkpoint is a base file (`global_map.ssgmap`) plus a journal folder
//! (`global_map.journal/`) of what each bin changed since the base was written, plus a
//! tiles folder (`global_map.tiles/`) of the tiles paged out of memory
//! ([`super::map_store`] writes all three; [`crate::fusion::JournalWriter`] and
//! [`crate::fusion::PagedTile`] have the formats).
//! Restoring loads the base and replays the journal ([`restore`]); a record torn by a crash
//! at the journal's end is cut, and the node says how much it kept.
//!
//! Resume rule: a node with an out folder that holds a checkpoint starts from it unless told
//! to start fresh ([`StartMap::Fresh`], `run --fresh`). The resumed map keeps its settings,
//! Gaussians and ids; the next bin id follows its last bin; its increments continue its
//! sequence numbers; its epoch goes up by one. A checkpoint that does not load (damaged,
//! truncated, another version, a journal without its base) stops the node with
//! [`RestoreError::Unreadable`], naming the file and why, and the files are left as they
//! are; a fresh start moves the base, the journal and the tiles aside (to `<name>.replaced-<unix
//! seconds>`) rather than overwriting them, so no saved map is ever replaced by an empty one.
//! The exported map file is in the format `run --format` names (PLY by default); a map of
//! more than [`ONE_FILE_MAX`] Gaussians is exported one file per tile, with an index.
//! Every file is replaced atomically ([`renderer::atomic`]).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use glam::{DAffine3, DVec2, DVec3};

use renderer::formats::MapFormat;

use crate::error_text::error_chain;
use crate::fusion::{
    bev_image, collect_garbage, create_dir_durably, local_set, save_bev_png, segments, AtTornTail,
    BevView, FusionConfig, GaussianId, GlobalMap, Replay, StoreError, TileKey, WorldGaussian,
};

/// The checkpoint's base file name in the out folder.
pub const CHECKPOINT: &str = "global_map.ssgmap";

/// The checkpoint's journal folder name in the out folder.
pub const JOURNAL: &str = "global_map.journal";

/// The checkpoint's folder of paged-out tiles in the out folder.
pub const TILES: &str = "global_map.tiles";

/// How a node with an out folder starts its global map.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StartMap {
    /// From the checkpoint in the out folder when there is one, else empty.
    #[default]
    Resume,
    /// Empty; an existing checkpoint is moved aside first.
    Fresh,
}

/// Why the node would not start on its out folder's checkpoint.
#[derive(Debug, thiserror::Error)]
pub enum RestoreError {
    /// The checkpoint exists but does not load; it is left untouched.
    #[error("{source}; the node will not start over a saved map it cannot read: move the file away or start fresh (`run --fresh` keeps it as {CHECKPOINT}.replaced-<time>)")]
    Unreadable {
        /// Why it does not load (names the file).
        #[source]
        source: StoreError,
    },
    /// A fresh start could not move the old checkpoint aside.
    #[error("moving {from} aside to {to}: {source}")]
    MoveAside {
        /// The checkpoint.
        from: PathBuf,
        /// Where it was to go.
        to: PathBuf,
        /// The system error.
        #[source]
        source: std::io::Error,
    },
}

/// Why the global map's files could not be written when the node stopped (the message
/// names the file and the cause).
#[derive(Debug, thiserror::Error)]
#[error("exporting the global map: {0}")]
pub struct ExportError(String);

/// The map a node starts with, and where it came from.
#[derive(Debug)]
pub struct Start {
    /// The map to fuse into.
    pub map: GlobalMap,
    /// The checkpoint it was resumed from (`None`: a new, empty map).
    pub resumed_from: Option<PathBuf>,
    /// What replaying the journal did, for a resumed map.
    pub replay: Option<Replay>,
    /// Where a fresh start moved the old checkpoint's files.
    pub moved_aside: Vec<PathBuf>,
    /// The fusion settings asked for that a resumed map did not take ([`settings_kept`]).
    pub settings_kept: Vec<SettingKept>,
}

/// A fusion setting the node was asked for that its resumed map does not take: a map keeps
/// the settings it was saved with, because its cells and tiles are laid out by them and what
/// it fused was chosen by them (`--fresh` starts a map with the new ones).
#[derive(Clone, Debug, PartialEq)]
pub struct SettingKept {
    /// The setting's `run` flag.
    pub flag: &'static str,
    /// The value the map keeps.
    pub stored: String,
    /// The value asked for.
    pub asked: String,
}

/// The settings of `asked` that differ from the `stored` ones of a resumed map, each with
/// its `run` flag (settings with no flag are compared too, under their field's name).
pub fn settings_kept(stored: &FusionConfig, asked: &FusionConfig) -> Vec<SettingKept> {
    let pairs = [
        ("--tile-m", stored.tile_side(), asked.tile_side()),
        (
            "--map-keep-range",
            f64::from(stored.keep.max_range_m),
            f64::from(asked.keep.max_range_m),
        ),
        (
            "min_confidence",
            f64::from(stored.keep.min_confidence),
            f64::from(asked.keep.min_confidence),
        ),
        ("cell_size", stored.cell_size, asked.cell_size),
        (
            "opacity_floor",
            f64::from(stored.opacity_floor),
            f64::from(asked.opacity_floor),
        ),
        (
            "max_gaussians",
            stored.max_gaussians as f64,
            asked.max_gaussians as f64,
        ),
    ];
    pairs
        .into_iter()
        .filter(|(_, a, b)| a.to_bits() != b.to_bits())
        .map(|(flag, stored, asked)| SettingKept {
            flag,
            stored: stored.to_string(),
            asked: asked.to_string(),
        })
        .collect()
}

/// A map restored from an out folder's checkpoint.
#[derive(Debug)]
pub struct Restored {
    /// The map: the base with the journal replayed.
    pub map: GlobalMap,
    /// What the replay did (records applied, a torn tail cut).
    pub replay: Replay,
}

/// The map of the checkpoint in `dir` (`None` when it holds none): the base file with every
/// journal record past it replayed ([`GlobalMap::replay_journal`]), a torn last record
/// handled by `at_torn`. Journal segments without a base are an error.
pub fn restore(dir: &Path, at_torn: AtTornTail) -> Result<Option<Restored>, StoreError> {
    restore_files(&dir.join(CHECKPOINT), &dir.join(JOURNAL), at_torn)
}

/// [`restore`] from a base file and a journal folder named apart.
pub fn restore_files(
    base: &Path,
    journal: &Path,
    at_torn: AtTornTail,
) -> Result<Option<Restored>, StoreError> {
    let journal = segments(journal)?;
    if !base.exists() {
        return match journal.first() {
            None => Ok(None),
            Some(path) => Err(StoreError::Invalid {
                path: path.clone(),
                offset: 0,
                what: "journal segment without its base file",
            }),
        };
    }
    let mut map = GlobalMap::load(base)?;
    let replay = map.replay_journal(&journal, &tiles_of(base), at_torn)?;
    Ok(Some(Restored { map, replay }))
}

/// The journal folder beside a checkpoint's base file: `<stem>.journal`
/// (`global_map.ssgmap` -> `global_map.journal`).
pub fn journal_of(base: &Path) -> PathBuf {
    base.with_extension("journal")
}

/// Why a region of the whole map was not read.
#[derive(Debug, thiserror::Error)]
pub enum RegionReadError {
    /// The region may hold more Gaussians than one answer holds.
    #[error("the region may hold {upper} Gaussians, more than the {at_most} one answer holds: ask for a smaller region")]
    TooLarge {
        /// Gaussians in memory in the region plus every Gaussian of the tiles on disk it meets.
        upper: u64,
        /// The most one answer holds.
        at_most: u64,
    },
    /// A tile file the region meets does not read.
    #[error("reading the region's tiles: {0}")]
    Tile(#[from] StoreError),
}

/// The Gaussians whose centres lie in the ground box `min`-`max` (world x-y, metres), in id
/// order: those in memory and those of the paged-out tiles the box meets, read from the
/// tiles folder `tiles`. Refused before anything is read when the box may hold more than
/// `at_most` (counting the whole of each tile on disk it meets).
pub fn gaussians_in_whole(
    map: &GlobalMap,
    tiles: &Path,
    min: DVec2,
    max: DVec2,
    at_most: u64,
) -> Result<Vec<(GaussianId, WorldGaussian)>, RegionReadError> {
    let mut found: Vec<(GaussianId, WorldGaussian)> = map
        .gaussians_in(min, max)
        .into_iter()
        .map(|(id, g)| (id, *g))
        .collect();
    let on_disk = map.paged_tiles_in(min, max);
    let upper = found.len() as u64 + on_disk.iter().map(|(_, p)| p.count).sum::<u64>();
    if upper > at_most {
        return Err(RegionReadError::TooLarge { upper, at_most });
    }
    for (tile, _) in on_disk {
        let read = map.read_paged_tile(tiles, tile)?;
        found.extend(read.into_iter().filter(|(_, g)| {
            let p = g.position.truncate();
            p.cmpge(min).all() && p.cmple(max).all()
        }));
    }
    found.sort_unstable_by_key(|(id, _)| *id);
    Ok(found)
}

/// The tiles folder beside a checkpoint's base file: `<stem>.tiles`.
pub fn tiles_of(base: &Path) -> PathBuf {
    base.with_extension("tiles")
}

/// Every Gaussian of the map whose base file is `base`: those in memory and those of its
/// paged-out tiles, read from the tiles folder beside it (in memory at once: the whole map).
pub fn whole_map(map: &GlobalMap, base: &Path) -> Result<Vec<WorldGaussian>, StoreError> {
    let mut out: Vec<WorldGaussian> = map.gaussians().map(|(_, g)| *g).collect();
    let dir = tiles_of(base);
    for tile in map.paged_tiles().keys() {
        let read = map.read_paged_tile(&dir, *tile)?;
        out.extend(read.into_iter().map(|(_, g)| g));
    }
    Ok(out)
}

/// The map to start with under `out_dir` (`None`: no files, `empty`), by the rule in the
/// module doc; `empty` is the new map with the node's fusion settings.
pub fn start_map(
    out_dir: Option<&Path>,
    empty: GlobalMap,
    how: StartMap,
) -> Result<Start, RestoreError> {
    let mut start = Start {
        map: empty,
        resumed_from: None,
        replay: None,
        moved_aside: Vec::new(),
        settings_kept: Vec::new(),
    };
    let Some(dir) = out_dir else {
        return Ok(start);
    };
    let files = [dir.join(CHECKPOINT), dir.join(JOURNAL), dir.join(TILES)];
    match how {
        StartMap::Resume => {
            let restored = restore(dir, AtTornTail::Cut)
                .map_err(|source| RestoreError::Unreadable { source })?;
            if let Some(mut r) = restored {
                start.settings_kept = settings_kept(r.map.config(), start.map.config());
                r.map.resume();
                start.map = r.map;
                start.replay = Some(r.replay);
                start.resumed_from = Some(files[0].clone());
            }
        }
        StartMap::Fresh => {
            let secs = SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0, |d| d.as_secs());
            for from in files.into_iter().filter(|f| f.exists()) {
                let name = from.file_name().unwrap_or_default().to_string_lossy();
                let to = from.with_file_name(format!("{name}.replaced-{secs}"));
                std::fs::rename(&from, &to).map_err(|source| RestoreError::MoveAside {
                    from: from.clone(),
                    to: to.clone(),
                    source,
                })?;
                start.moved_aside.push(to);
            }
        }
    }
    Ok(start)
}

/// Saves `map` as the checkpoint's base in `dir` (created if missing), atomically, then
/// removes the journal's segments, which the base now holds, and the tile files the base
/// does not name. A crash between the two leaves files that a restore skips.
pub fn checkpoint(map: &GlobalMap, dir: &Path) -> Result<(), StoreError> {
    create_dir_durably(dir)?;
    map.save(dir.join(CHECKPOINT))?;
    for path in segments(&dir.join(JOURNAL))? {
        std::fs::remove_file(&path).map_err(|source| StoreError::Io { path, source })?;
    }
    collect_garbage(&dir.join(TILES), map.paged_tiles(), map.increments())?;
    Ok(())
}

/// The most Gaussians [`export`] writes as one map file: a larger map is written one file per
/// tile plus an index (`global_map_tiles/`). 4 M Gaussians are a PLY of 288 MB, about what
/// desktop splat viewers open.
pub const ONE_FILE_MAX: u64 = 4_000_000;

/// Writes the checkpoint, the whole global map (in memory and paged out) and a bird's-eye PNG,
/// each atomically: [`export_with_limit`] at [`ONE_FILE_MAX`].
pub fn export(map: &GlobalMap, dir: &Path, format: MapFormat) -> Result<(), ExportError> {
    export_with_limit(map, dir, format, ONE_FILE_MAX)
}

/// Writes the checkpoint, the whole global map in `format` (positions relative to the latest
/// bin's origin, which `global_map_origin.json` records; see [`renderer::formats`]) and a
/// bird's-eye PNG, each atomically. A map of at most `one_file_max` Gaussians is one file,
/// `global_map.<ply|spz|glb>`; a larger one is one file per tile, `global_map_tiles/<x>_<y>.<ext>`
/// (the same origin, so the tiles overlay), plus `global_map_tiles/index.json` (origin, tile
/// side, format, and per tile its key, file, count and world bounds), read one tile at a time.
pub fn export_with_limit(
    map: &GlobalMap,
    dir: &Path,
    format: MapFormat,
    one_file_max: u64,
) -> Result<(), ExportError> {
    let err = |e: &dyn std::fmt::Display| ExportError(e.to_string());
    checkpoint(map, dir).map_err(|e| err(&e))?;
    let Some(origin) = map.latest_origin() else {
        return Ok(());
    };
    let frame = DAffine3::from_translation(origin);
    let json = format!(
        "{{\"x\": {}, \"y\": {}, \"z\": {}}}\n",
        origin.x, origin.y, origin.z
    );
    let origin_file = dir.join("global_map_origin.json");
    renderer::atomic::write_bytes_atomic(&origin_file, json.as_bytes())
        .map_err(|e| err(&format!("{}: {e}", origin_file.display())))?;
    let view = BevView::export(DVec2::new(origin.x, origin.y));
    let image = if map.total_len() <= one_file_max {
        let whole = whole_map(map, &dir.join(CHECKPOINT)).map_err(|e| err(&e))?;
        save_local(
            &whole,
            frame,
            &dir.join(format!("global_map.{format}")),
            format,
        )?;
        bev_image(whole.iter(), &view)
    } else {
        export_tiles(map, dir, format, frame)?;
        // The view's 128 m around the latest bin lie within the tiles kept in memory.
        let (min, max) = view.ground_box();
        bev_image(
            map.gaussians_in(min, max).into_iter().map(|(_, g)| g),
            &view,
        )
    };
    let image = image.map_err(|e| err(&e))?;
    let bev = dir.join("global_map_bev.png");
    save_bev_png(&image, &bev).map_err(|e| err(&format!("{}: {e}", bev.display())))
}

/// Writes `gaussians` to `file` in `format`, positions in `frame` (world to file).
fn save_local(
    gaussians: &[WorldGaussian],
    frame: DAffine3,
    file: &Path,
    format: MapFormat,
) -> Result<(), ExportError> {
    let err = |e: &dyn std::fmt::Display| ExportError(e.to_string());
    let set = local_set(gaussians.iter(), frame).map_err(|e| err(&e))?;
    renderer::formats::save_map(&set, file, format)
        .map_err(|e| err(&format!("{}: {}", file.display(), error_chain(&e))))?;
    Ok(())
}

/// The tile files and index of [`export_with_limit`], in `dir/global_map_tiles/` (emptied
/// first).
fn export_tiles(
    map: &GlobalMap,
    dir: &Path,
    format: MapFormat,
    frame: DAffine3,
) -> Result<(), ExportError> {
    let err = |e: &dyn std::fmt::Display| ExportError(e.to_string());
    let out = dir.join("global_map_tiles");
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).map_err(|e| err(&format!("{}: {e}", out.display())))?;
    let config = map.config();
    let mut in_memory: BTreeMap<TileKey, Vec<WorldGaussian>> = BTreeMap::new();
    for (_, g) in map.gaussians() {
        in_memory
            .entry(config.tile_of(g.position))
            .or_default()
            .push(*g);
    }
    let keys: BTreeSet<TileKey> = in_memory
        .keys()
        .chain(map.paged_tiles().keys())
        .copied()
        .collect();
    let tiles_dir = dir.join(TILES);
    let mut index = Vec::with_capacity(keys.len());
    for key in keys {
        let mut gaussians = in_memory.remove(&key).unwrap_or_default();
        if map.paged_tiles().contains_key(&key) {
            let read = map.read_paged_tile(&tiles_dir, key).map_err(|e| err(&e))?;
            gaussians.extend(read.into_iter().map(|(_, g)| g));
        }
        let name = format!("{}_{}.{format}", key.0, key.1);
        save_local(&gaussians, frame, &out.join(&name), format)?;
        let (min, max) = gaussians.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), g| (lo.min(g.position), hi.max(g.position)),
        );
        index.push(serde_json::json!({
            "tile": [key.0, key.1],
            "file": name,
            "count": gaussians.len(),
            "min": min.to_array(),
            "max": max.to_array(),
        }));
    }
    let origin = frame.translation;
    let json = serde_json::json!({
        "origin": origin.to_array(),
        "tile_m": config.tile_side(),
        "format": format.to_string(),
        "gaussians": map.total_len(),
        "tiles": index,
    });
    let file = out.join("index.json");
    let text = serde_json::to_string_pretty(&json).map_err(|e| err(&e))?;
    renderer::atomic::write_bytes_atomic(&file, text.as_bytes())
        .map_err(|e| err(&format!("{}: {e}", file.display())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::Keep;

    fn config(tile_m: f64, max_range_m: f32) -> FusionConfig {
        FusionConfig {
            tile_m,
            keep: Keep {
                max_range_m,
                ..Keep::default()
            },
            ..FusionConfig::default()
        }
    }

    #[test]
    fn a_resumed_map_names_the_settings_it_keeps_against_the_ones_asked_for() {
        let dir = std::env::temp_dir().join(format!("ss-settings-kept-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        checkpoint(&GlobalMap::new(config(64.0, 20.0)).unwrap(), &dir).unwrap();
        let resume = |asked: FusionConfig| {
            start_map(Some(&dir), GlobalMap::new(asked).unwrap(), StartMap::Resume).unwrap()
        };

        let same = resume(config(64.0, 20.0));
        assert!(same.resumed_from.is_some());
        assert_eq!(same.settings_kept, []);

        let other = resume(config(32.0, f32::INFINITY));
        let flags: Vec<_> = other.settings_kept.iter().map(|k| k.flag).collect();
        assert_eq!(flags, ["--tile-m", "--map-keep-range"]);
        assert_eq!(other.settings_kept[0].stored, "64");
        assert_eq!(other.settings_kept[0].asked, "32");
        assert_eq!(other.settings_kept[1].asked, "inf");
        // The map keeps what it was saved with.
        assert_eq!(other.map.config().tile_m, 64.0);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
