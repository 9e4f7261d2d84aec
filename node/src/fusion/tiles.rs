//! Tiles: the world map's ground cut into squares of [`FusionConfig::tile_m`] metres (whole
//! ground columns of the cell index), the unit in which a long drive's map is kept on disk
//! and out of memory.
//!
//! A tile is *paged out* by taking all its Gaussians out of the map ([`GlobalMap::take_tile`])
//! and writing them to a tile file ([`write_tile`]); the map remembers it as
//! [`PagedTile`] (its version and count) and saves that table with its base. A tile the
//! vehicle comes back to is *paged in* ([`GlobalMap::put_tile`]): the same ids and Gaussians
//! return, so later bins fuse into it by the usual rule instead of layering a copy on top.
//! Paging is no change to the map's content: increments never mention it, and nothing paged
//! out is removed from what subscribers hold.
//!
//! Tile files are versioned: `<x>_<y>_<version>.sstile` in the tiles folder, the version being
//! the map's sequence number when the tile went out. A journal record names the versions it
//! paged in and out, so replaying any stretch of the journal reads the files as they were
//! then; files no base or journal record can still name are removed by
//! [`collect_garbage`]. Format (little endian): magic `SSGTILE\n`, version u32 (1), tile x
//! i64, tile y i64, count u64, the Gaussians in the base file's record layout (ids
//! increasing), an FNV-1a 64 checksum (u64) of everything before it.

use std::collections::BTreeMap;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};

use super::cells::{cells_per_column, column_side};
use super::snapshot::{fnv1a, put_gaussian, Reader, RECORD_BYTES};
use super::{cell_of, FusionConfig, GaussianId, GlobalMap, StoreError, WorldGaussian};

const MAGIC: &[u8; 8] = b"SSGTILE\n";
const VERSION: u32 = 1;
const EXT: &str = "sstile";

/// A tile's integer ground coordinates: `floor(x / tile side)`, `floor(y / tile side)`.
pub type TileKey = (i64, i64);

/// A tile that is on disk, not in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PagedTile {
    /// The version of its file (the map's sequence number when it was paged out).
    pub version: u64,
    /// Gaussians in it.
    pub count: u64,
}

/// One tile moving between memory and disk, as a journal record lists it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PageEvent {
    /// The tile's file of this version was read into the map.
    In(TileKey, PagedTile),
    /// The tile was taken out of the map and written to the file of this version.
    Out(TileKey, PagedTile),
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> StoreError + '_ {
    move |source| StoreError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The file of `tile` at `version` in the tiles folder `dir`.
pub fn tile_path(dir: &Path, tile: TileKey, version: u64) -> PathBuf {
    dir.join(format!("{}_{}_{version}.{EXT}", tile.0, tile.1))
}

/// The tile and version a tile file's name gives (`None` for other files).
fn parse_name(path: &Path) -> Option<(TileKey, u64)> {
    if path.extension().is_none_or(|e| e != EXT) {
        return None;
    }
    let stem = path.file_stem()?.to_str()?;
    let mut parts = stem.rsplitn(3, '_');
    let version = parts.next()?.parse().ok()?;
    let y = parts.next()?.parse().ok()?;
    let x = parts.next()?.parse().ok()?;
    Some(((x, y), version))
}

/// Writes a tile's Gaussians to its file of `version` in `dir` (created if missing),
/// atomically and durably: the file is whole on disk before this returns.
pub fn write_tile(
    dir: &Path,
    tile: TileKey,
    version: u64,
    gaussians: &[(GaussianId, WorldGaussian)],
) -> Result<(), StoreError> {
    super::create_dir_durably(dir)?;
    let mut b = Vec::with_capacity(40 + gaussians.len() * RECORD_BYTES);
    b.extend_from_slice(MAGIC);
    b.extend_from_slice(&VERSION.to_le_bytes());
    b.extend_from_slice(&tile.0.to_le_bytes());
    b.extend_from_slice(&tile.1.to_le_bytes());
    b.extend_from_slice(&(gaussians.len() as u64).to_le_bytes());
    for (id, g) in gaussians {
        put_gaussian(&mut b, *id, g);
    }
    let sum = fnv1a(&b);
    b.extend_from_slice(&sum.to_le_bytes());
    let path = tile_path(dir, tile, version);
    renderer::atomic::write_bytes_atomic(&path, &b).map_err(io_error(&path))
}

/// Reads the file of `tile` at `paged.version` from `dir`; it must hold `paged.count`
/// Gaussians of that tile (tiles of `config`), ids increasing, every field finite.
pub fn read_tile(
    dir: &Path,
    tile: TileKey,
    paged: PagedTile,
    config: &FusionConfig,
) -> Result<Vec<(GaussianId, WorldGaussian)>, StoreError> {
    let path = tile_path(dir, tile, paged.version);
    let bytes = std::fs::read(&path).map_err(io_error(&path))?;
    let mut r = Reader {
        bytes: &bytes,
        pos: 0,
        path: &path,
    };
    if r.take(MAGIC.len())? != MAGIC {
        return Err(StoreError::BadMagic { path });
    }
    let version = r.u32()?;
    if version != VERSION {
        return Err(StoreError::UnsupportedVersion { path, version });
    }
    if bytes.len() < r.pos + 8 {
        return Err(r.invalid(r.pos, "tile file shorter than its checksum"));
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    if fnv1a(body) != u64::from_le_bytes(sum.try_into().unwrap_or_default()) {
        return Err(StoreError::Checksum { path });
    }
    r.bytes = body;
    let at = r.pos;
    let key = (r.u64()? as i64, r.u64()? as i64);
    let count = r.u64()?;
    if key != tile || count != paged.count {
        return Err(r.invalid(at, "tile file of another tile or another count"));
    }
    if count.checked_mul(RECORD_BYTES as u64) != Some((r.bytes.len() - r.pos) as u64) {
        return Err(r.invalid(at + 16, "count does not match the file length"));
    }
    let mut out = Vec::with_capacity(count as usize);
    for _ in 0..count {
        let at = r.pos;
        let (id, g) = r.gaussian()?;
        if out.last().is_some_and(|(last, _)| id <= *last) || config.tile_of(g.position) != tile {
            return Err(r.invalid(at, "ids not increasing or a Gaussian outside its tile"));
        }
        out.push((id, g));
    }
    Ok(out)
}

/// Removes every tile file in `dir` that neither `keep` (a map's paged tiles) names nor is
/// newer than `upto` (the sequence number of the base that `keep` belongs to): no record
/// past that base can name it. Returns how many files were removed.
pub fn collect_garbage(
    dir: &Path,
    keep: &BTreeMap<TileKey, PagedTile>,
    upto: u64,
) -> Result<usize, StoreError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(io_error(dir)(e)),
    };
    let mut removed = 0;
    for entry in entries {
        let path = entry.map_err(io_error(dir))?.path();
        let Some((tile, version)) = parse_name(&path) else {
            continue;
        };
        let named = keep.get(&tile).is_some_and(|p| p.version == version);
        if !named && version <= upto {
            std::fs::remove_file(&path).map_err(io_error(&path))?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// Ground distance from `point` to the tile's square (0 inside it).
pub fn tile_distance(tile: TileKey, tile_m: f64, point: DVec3) -> f64 {
    let lo = DVec2::new(tile.0 as f64, tile.1 as f64) * tile_m;
    let hi = lo + tile_m;
    let p = point.truncate();
    (p.clamp(lo, hi) - p).length()
}

impl FusionConfig {
    /// The tile side actually used: [`FusionConfig::tile_m`] rounded to whole ground columns
    /// of the cell index, so that every cell lies in exactly one tile.
    pub fn tile_side(&self) -> f64 {
        self.cells_per_tile() as f64 * self.cell_size
    }

    /// Ground columns per tile side.
    fn columns_per_tile(&self) -> i64 {
        (self.tile_m / column_side(self.cell_size)).round().max(1.0) as i64
    }

    fn cells_per_tile(&self) -> i64 {
        self.columns_per_tile() * cells_per_column(self.cell_size)
    }

    /// The tile holding a world position (finite): the tile of its cell, so a Gaussian is
    /// always in the tile it is paged with, whatever rounding a division of its position
    /// by the tile side would make at a tile's edge.
    pub fn tile_of(&self, position: DVec3) -> TileKey {
        let cell = cell_of(position, self.cell_size);
        let n = self.cells_per_tile();
        (cell.0.div_euclid(n), cell.1.div_euclid(n))
    }
}

impl GlobalMap {
    /// The tiles on disk, with their versions and counts.
    pub fn paged_tiles(&self) -> &BTreeMap<TileKey, PagedTile> {
        &self.paged
    }

    /// The paged-out tiles whose squares meet the ground box `min`-`max` (world x-y, metres),
    /// in tile order. It visits the rows of tiles the box spans, each as one range of the
    /// table, so a query costs the tiles near the box, not every tile the drive has paged
    /// out; a box spanning more rows than there are tiles on disk visits the table instead.
    pub fn paged_tiles_in(&self, min: DVec2, max: DVec2) -> Vec<(TileKey, PagedTile)> {
        let side = self.config.tile_side();
        let meets = |t: &TileKey| {
            let lo = DVec2::new(t.0 as f64, t.1 as f64) * side;
            let hi = lo + side;
            lo.cmple(max).all() && hi.cmpge(min).all()
        };
        // A tile meets the box only if its index lies in `[floor(min / side) - 1,
        // floor(max / side)]` on each axis (the `- 1`: a tile whose far edge touches `min`).
        // Casts saturate, and NaN gives 0: the exact test below decides.
        let first = |v: f64| ((v / side).floor() as i64).saturating_sub(1);
        let last = |v: f64| (v / side).floor() as i64;
        let (x0, x1, y0, y1) = (first(min.x), last(max.x), first(min.y), last(max.y));
        if x0 > x1 || y0 > y1 {
            return Vec::new();
        }
        let pick = |(t, p): (&TileKey, &PagedTile)| meets(t).then_some((*t, *p));
        let rows = i128::from(x1) - i128::from(x0) + 1;
        if rows > self.paged.len() as i128 {
            return self.paged.iter().filter_map(pick).collect();
        }
        (x0..=x1)
            .flat_map(|x| self.paged.range((x, y0)..=(x, y1)))
            .filter_map(pick)
            .collect()
    }

    /// The paged-out tiles within `radius` metres of `point` on the ground
    /// ([`tile_distance`]), in tile order; found as [`GlobalMap::paged_tiles_in`] finds them.
    pub fn paged_tiles_near(&self, point: DVec3, radius: f64) -> Vec<TileKey> {
        let side = self.config.tile_side();
        let centre = point.truncate();
        self.paged_tiles_in(centre - radius, centre + radius)
            .into_iter()
            .map(|(t, _)| t)
            .filter(|t| tile_distance(*t, side, point) <= radius)
            .collect()
    }

    /// Reads paged-out `tile`'s file from the tiles folder `dir`, as the map recorded it (its
    /// version and count).
    pub fn read_paged_tile(
        &self,
        dir: &Path,
        tile: TileKey,
    ) -> Result<Vec<(GaussianId, WorldGaussian)>, StoreError> {
        let paged = self.paged.get(&tile).ok_or_else(|| StoreError::Invalid {
            path: dir.to_path_buf(),
            offset: 0,
            what: "the tile is not paged out",
        })?;
        read_tile(dir, tile, *paged, &self.config)
    }

    /// Reads paged-out `tile` back into memory from the tiles folder `dir`
    /// ([`GlobalMap::read_paged_tile`], [`GlobalMap::put_tile`]); what the map had recorded
    /// of it.
    pub fn page_in(&mut self, dir: &Path, tile: TileKey) -> Result<PagedTile, StoreError> {
        let gaussians = self.read_paged_tile(dir, tile)?;
        let paged = self.paged[&tile];
        self.put_tile(tile, gaussians)
            .map_err(|what| StoreError::Invalid {
                path: tile_path(dir, tile, paged.version),
                offset: 0,
                what,
            })?;
        Ok(paged)
    }

    /// Gaussians in the whole map: those in memory plus those in paged-out tiles (saturating:
    /// the counts of a damaged checkpoint can add up past `u64::MAX`).
    pub fn total_len(&self) -> u64 {
        self.paged
            .values()
            .fold(self.len() as u64, |n, p| n.saturating_add(p.count))
    }

    /// The tiles with Gaussians in memory, with their counts, in tile order.
    pub fn resident_tiles(&self) -> BTreeMap<TileKey, u64> {
        let per_tile = self.config.columns_per_tile();
        let mut out = BTreeMap::new();
        for (column, n) in self.cells.column_counts() {
            let tile = (column.0.div_euclid(per_tile), column.1.div_euclid(per_tile));
            *out.entry(tile).or_insert(0) += n;
        }
        out
    }

    /// Takes every Gaussian of `tile` out of memory (in id order) and records the tile as
    /// paged out at `version`; the caller writes them to the tile's file. A tile with
    /// nothing in memory gives nothing and is not recorded. A tile already paged out must be
    /// paged in first (its file would be forgotten): an error, changing nothing.
    pub fn take_tile(
        &mut self,
        tile: TileKey,
        version: u64,
    ) -> Result<Vec<(GaussianId, WorldGaussian)>, &'static str> {
        if self.paged.contains_key(&tile) {
            return Err("the tile is paged out already");
        }
        let per_tile = self.config.columns_per_tile();
        // The tile's ground columns; a tile so far out that they overflow holds none (a
        // journal record may name any tile).
        let columns = |t: i64| {
            let first = t.checked_mul(per_tile)?;
            Some(first..first.checked_add(per_tile)?)
        };
        let (Some(xs), Some(ys)) = (columns(tile.0), columns(tile.1)) else {
            return Ok(Vec::new());
        };
        let mut ids = Vec::new();
        for cx in xs {
            for cy in ys.clone() {
                for key in self.cells.column_cells((cx, cy)) {
                    ids.extend(self.cells.remove(key));
                }
            }
        }
        ids.sort_unstable();
        let out: Vec<_> = ids
            .into_iter()
            .filter_map(|id| self.gaussians.remove(&id).map(|g| (id, g)))
            .collect();
        if !out.is_empty() {
            let count = out.len() as u64;
            self.paged.insert(tile, PagedTile { version, count });
        }
        Ok(out)
    }

    /// Puts a paged-out tile's Gaussians (as [`read_tile`] gives them) back into memory,
    /// with their ids and cells as they were, and forgets the tile's file. Errors, changing
    /// nothing, when the tile is not paged out or an id is already in the map.
    pub fn put_tile(
        &mut self,
        tile: TileKey,
        gaussians: Vec<(GaussianId, WorldGaussian)>,
    ) -> Result<(), &'static str> {
        if !self.paged.contains_key(&tile) {
            return Err("the tile is not paged out");
        }
        if gaussians
            .iter()
            .any(|(id, _)| id.0 >= self.next_id || self.gaussians.contains_key(id))
        {
            return Err("a paged-in id is in the map or was never assigned");
        }
        self.paged.remove(&tile);
        for (id, g) in gaussians {
            let key = cell_of(g.position, self.config.cell_size);
            self.cells.push(key, id, g.confidence);
            self.gaussians.insert(id, g);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A map whose table lists `tiles` as paged out (their files are not needed here).
    fn map_with_paged(tiles: impl IntoIterator<Item = TileKey>) -> GlobalMap {
        let mut map = GlobalMap::new(FusionConfig::default()).expect("default config");
        for (i, t) in tiles.into_iter().enumerate() {
            let paged = PagedTile {
                version: i as u64,
                count: 1,
            };
            map.paged.insert(t, paged);
        }
        map
    }

    #[test]
    fn paged_tiles_in_a_box_are_those_the_whole_table_gives() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        // A road of tiles, a block around the origin and a few far away.
        let tiles = (0..400)
            .map(|i| (i, i / 3))
            .chain((-5..5).flat_map(|x| (-5..5).map(move |y| (x, y))))
            .chain([(i64::MAX, 0), (i64::MIN, i64::MIN), (0, i64::MAX)]);
        let map = map_with_paged(tiles);
        let side = map.config().tile_side();
        let brute = |min: DVec2, max: DVec2| -> Vec<TileKey> {
            map.paged
                .keys()
                .filter(|t| {
                    let lo = DVec2::new(t.0 as f64, t.1 as f64) * side;
                    lo.cmple(max).all() && (lo + side).cmpge(min).all()
                })
                .copied()
                .collect()
        };
        let keys = |v: Vec<(TileKey, PagedTile)>| v.into_iter().map(|(t, _)| t).collect::<Vec<_>>();
        for _ in 0..500 {
            let a = DVec2::new(rng.random_range(-2e3..3e4), rng.random_range(-2e3..1e4));
            let b = a + DVec2::new(rng.random_range(-100.0..2e3), rng.random_range(-100.0..2e3));
            assert_eq!(keys(map.paged_tiles_in(a, b)), brute(a, b), "box {a} {b}");
        }
        // Edges touching, a point, inverted, unbounded and NaN boxes.
        let edge = DVec2::splat(side);
        for (min, max) in [
            (edge, edge),
            (DVec2::ZERO, DVec2::ZERO),
            (edge * 3.0, edge * -3.0),
            (DVec2::splat(f64::NEG_INFINITY), DVec2::splat(f64::INFINITY)),
            (DVec2::splat(f64::NAN), DVec2::splat(1e3)),
            (DVec2::splat(-1e300), DVec2::splat(1e300)),
        ] {
            assert_eq!(
                keys(map.paged_tiles_in(min, max)),
                brute(min, max),
                "box {min} {max}"
            );
        }
    }

    #[test]
    fn paged_tiles_near_a_point_are_those_within_the_radius() {
        let map = map_with_paged((-20..20).flat_map(|x| (-20..20).map(move |y| (x, y))));
        let side = map.config().tile_side();
        let p = DVec3::new(10.0, -30.0, 2.0);
        for radius in [0.0, 1.0, side, 3.5 * side, 1e9, f64::INFINITY] {
            let want: Vec<TileKey> = map
                .paged
                .keys()
                .filter(|t| tile_distance(**t, side, p) <= radius)
                .copied()
                .collect();
            assert_eq!(map.paged_tiles_near(p, radius), want, "radius {radius}");
        }
        assert!(map.paged_tiles_near(p, f64::NAN).is_empty());
    }
}
