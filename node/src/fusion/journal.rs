//! The global map's journal: an append-only record of what each bin changed, so keeping a
//! map on disk costs each bin the size of its own change, not the size of the map.
//!
//! A saved map is a base file ([`GlobalMap::save`]) plus the journal's segments, files in one
//! folder named after the sequence number of their first record (`<20 digits>.ssgj`).
//! Restoring loads the base and replays every record past the base's sequence number, in
//! order ([`GlobalMap::replay_journal`]); records the base already holds are skipped, so a
//! base rewritten while its segments were still on disk restores the same map.
//!
//! Segment format (little endian): magic `SSGJRNL\n`, version u32 (2), then records, each a
//! payload length u32, the payload and an FNV-1a 64 checksum (u64) of the payload. Payload:
//! sequence number u64 (the map's increment count after the bin), epoch u64, bin id u64,
//! next id u64, latest origin flag u8 + 3 x f64, the tiles paged before the bin (version 2),
//! removed count u64 and the removed ids (u64 each), added count u64 and the added Gaussians
//! in the base file's record layout, the tiles paged after the bin (version 2). Paged tiles:
//! count u64, then per tile kind u8 (0 in, 1 out), x i64, y i64, file version u64, Gaussian
//! count u64 ([`super::tiles`]). Replay reads a paged-in tile's file from the tiles folder.
//!
//! A crash can tear only the newest segment's last record (records are appended and synced
//! in order); replay stops before such a tail and says how much it kept ([`TornTail`]); a
//! restarting node also cuts it from the file ([`AtTornTail::Cut`]). A write that failed
//! (a full disk, a failed sync) leaves bytes that the writer's next attempt follows with the
//! same records again ([`super::journal_writer`]); replay skips them ([`FailedWrite`]). A bad
//! record anywhere else is an error: the journal is damaged, and nothing is cut.

use std::fs::{File, OpenOptions};
use std::io::{BufReader, ErrorKind, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::cells::cell_of;
use super::snapshot::{fnv1a, put_f64s, put_gaussian, Reader, RECORD_BYTES};
use super::tiles::{PageEvent, PagedTile};
use super::{GaussianId, GlobalMap, Increment, StoreError, WorldGaussian};

const MAGIC: &[u8; 8] = b"SSGJRNL\n";
const VERSION: u32 = 2;
/// A new segment's first bytes: the magic, then the version (2) little endian.
pub(super) const HEADER: [u8; 12] = *b"SSGJRNL\n\x02\x00\x00\x00";
/// The oldest segment version read (without paged tiles).
const OLDEST_VERSION: u32 = 1;
/// Bytes before a segment's first record (a segment of this length holds no record).
pub const HEADER_BYTES: u64 = 12;
/// The file name ending of a segment.
const SEGMENT_EXT: &str = "ssgj";

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> StoreError + '_ {
    move |source| StoreError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The path of the segment whose first record has sequence number `first_sequence`.
pub fn segment_path(dir: &Path, first_sequence: u64) -> PathBuf {
    dir.join(format!("{first_sequence:020}.{SEGMENT_EXT}"))
}

/// The journal's segments in `dir`, oldest first; none when the folder does not exist.
pub fn segments(dir: &Path) -> Result<Vec<PathBuf>, StoreError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(io_error(dir)(e)),
    };
    let mut found = Vec::new();
    for entry in entries {
        let path = entry.map_err(io_error(dir))?.path();
        if path.extension().is_some_and(|e| e == SEGMENT_EXT) {
            found.push(path);
        }
    }
    found.sort();
    Ok(found)
}

/// Appends a list of paged tiles.
fn put_events(p: &mut Vec<u8>, events: &[PageEvent]) {
    p.extend_from_slice(&(events.len() as u64).to_le_bytes());
    for e in events {
        let (kind, tile, paged) = match e {
            PageEvent::In(t, p) => (0u8, t, p),
            PageEvent::Out(t, p) => (1u8, t, p),
        };
        p.push(kind);
        for v in [tile.0 as u64, tile.1 as u64, paged.version, paged.count] {
            p.extend_from_slice(&v.to_le_bytes());
        }
    }
}

/// Reads a list of paged tiles ([`put_events`]).
fn events(r: &mut Reader, len: usize) -> Result<Vec<PageEvent>, StoreError> {
    let at = r.pos;
    let count = r.u64()?;
    if count > (len / 33) as u64 {
        return Err(r.invalid(at, "paged tile count does not fit the record"));
    }
    (0..count)
        .map(|_| {
            let at = r.pos;
            let kind = r.array::<1>()?[0];
            let tile = (r.u64()? as i64, r.u64()? as i64);
            let paged = PagedTile {
                version: r.u64()?,
                count: r.u64()?,
            };
            match kind {
                0 => Ok(PageEvent::In(tile, paged)),
                1 => Ok(PageEvent::Out(tile, paged)),
                _ => Err(r.invalid(at, "paged tile kind is neither in nor out")),
            }
        })
        .collect()
}

/// A record encoded with its length and checksum.
pub(super) fn encode(
    map: &GlobalMap,
    inc: &Increment,
    before: &[PageEvent],
    after: &[PageEvent],
) -> Vec<u8> {
    let mut p = Vec::with_capacity(72 + inc.removed.len() * 8 + inc.added.len() * RECORD_BYTES);
    p.extend_from_slice(&map.increments().to_le_bytes());
    p.extend_from_slice(&map.epoch().to_le_bytes());
    p.extend_from_slice(&inc.bin_id.to_le_bytes());
    p.extend_from_slice(&map.next_id.to_le_bytes());
    let origin = map.latest_origin();
    p.push(u8::from(origin.is_some()));
    put_f64s(&mut p, &origin.unwrap_or(DVec3::ZERO).to_array());
    put_events(&mut p, before);
    p.extend_from_slice(&(inc.removed.len() as u64).to_le_bytes());
    for id in &inc.removed {
        p.extend_from_slice(&id.0.to_le_bytes());
    }
    p.extend_from_slice(&(inc.added.len() as u64).to_le_bytes());
    for (id, g) in &inc.added {
        put_gaussian(&mut p, *id, g);
    }
    put_events(&mut p, after);
    let mut record = Vec::with_capacity(p.len() + 12);
    record.extend_from_slice(&(p.len() as u32).to_le_bytes());
    let sum = fnv1a(&p);
    record.extend_from_slice(&p);
    record.extend_from_slice(&sum.to_le_bytes());
    record
}

/// One decoded record.
struct Record {
    sequence: u64,
    epoch: u64,
    bin_id: u64,
    next_id: u64,
    latest_origin: Option<DVec3>,
    before: Vec<PageEvent>,
    removed: Vec<GaussianId>,
    added: Vec<(GaussianId, WorldGaussian)>,
    after: Vec<PageEvent>,
}

fn decode(payload: &[u8], version: u32, path: &Path, offset: u64) -> Result<Record, StoreError> {
    let mut r = Reader {
        bytes: payload,
        pos: 0,
        path,
    };
    let sequence = r.u64()?;
    let epoch = r.u64()?;
    let bin_id = r.u64()?;
    let next_id = r.u64()?;
    let latest_origin = r.flagged(|r| r.f64s::<3>().map(DVec3::from_array))?;
    let bad = |what| StoreError::Invalid {
        path: path.to_path_buf(),
        offset: offset as usize,
        what,
    };
    if latest_origin.is_some_and(|o| !o.is_finite()) {
        return Err(bad("latest origin is not finite"));
    }
    let paged = |r: &mut Reader| match version {
        1 => Ok(Vec::new()),
        _ => events(r, payload.len()),
    };
    let before = paged(&mut r)?;
    let removed_count = r.u64()?;
    let fits = |count: u64, each: usize| count <= (payload.len() / each) as u64;
    if !fits(removed_count, 8) {
        return Err(bad("removed count does not fit the record"));
    }
    let removed = (0..removed_count)
        .map(|_| r.u64().map(GaussianId))
        .collect::<Result<Vec<_>, _>>()?;
    let added_count = r.u64()?;
    if !fits(added_count, RECORD_BYTES) {
        return Err(bad("added count does not fit the record"));
    }
    let added = (0..added_count)
        .map(|_| r.gaussian())
        .collect::<Result<Vec<_>, _>>()?;
    let after = paged(&mut r)?;
    if r.pos != payload.len() {
        return Err(bad("record longer than its contents"));
    }
    Ok(Record {
        sequence,
        epoch,
        bin_id,
        next_id,
        latest_origin,
        before,
        removed,
        added,
        after,
    })
}

/// A segment's last record, which a crash tore: replay stopped before it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TornTail {
    /// The segment.
    pub path: PathBuf,
    /// Bytes of the segment kept (its complete records).
    pub kept_bytes: u64,
    /// Bytes cut from its end.
    pub cut_bytes: u64,
}

/// What a replay does with an incomplete or corrupt record at the end of the last segment
/// that no complete record follows (see [`GlobalMap::replay_journal`] for the rest).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AtTornTail {
    /// Stops there and truncates the segment to its complete records (a node restarting).
    Cut,
    /// Stops there and leaves the file as it is (a reader, such as `export`).
    Stop,
    /// Fails (the compactor, whose segments were synced and closed).
    Fail,
}

/// Bytes of a write that failed, which a later copy of the same records follows: skipped
/// by replay, left in the file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FailedWrite {
    /// The segment.
    pub path: PathBuf,
    /// Where the bytes start.
    pub offset: u64,
    /// How many there are (to the next record, or to the segment's end).
    pub bytes: u64,
}

/// What a replay did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Replay {
    /// Records applied (those past the map's sequence number).
    pub applied: u64,
    /// Records skipped because the map already held them.
    pub skipped: u64,
    /// The torn tail at the end of the newest segment, if there was one (cut from the file
    /// with [`AtTornTail::Cut`]).
    pub torn: Option<TornTail>,
    /// Failed writes skipped because the records they held follow them again.
    pub failed_writes: Vec<FailedWrite>,
}

/// How a segment's reading ended.
enum End {
    /// At a record boundary.
    Clean,
    /// In a record that is incomplete or fails its checksum, starting at this offset, with
    /// no complete record after it.
    Torn(u64),
}

/// What follows a bad record in its segment.
enum After {
    /// Nothing that reads as a record.
    Nothing,
    /// A complete record with the sequence number the map expects next, at this offset:
    /// the bad bytes were a failed write, redone.
    Redone(u64),
    /// A complete record further on in the sequence: records were lost in between.
    Later,
}

/// The sequence number a segment's name gives its first record.
fn first_sequence(path: &Path) -> Option<u64> {
    path.file_stem()?.to_str()?.parse().ok()
}

impl GlobalMap {
    /// Applies, in order, every record of `segments` (oldest first, as [`segments`] lists
    /// them) whose sequence number is past the map's; earlier ones are skipped. Tiles a
    /// record pages in are read from the tiles folder `tiles`.
    ///
    /// A record that is incomplete or fails its checksum is one of three things:
    /// - a failed write (the disk was full, a sync failed): the same records follow it,
    ///   later in its segment or at the start of the next, so it is skipped and said in
    ///   [`Replay::failed_writes`];
    /// - a tail torn by a crash: nothing complete follows it in the last segment; it is
    ///   handled by `at_torn` and said in [`Replay::torn`];
    /// - damage: anything else (complete records after it that do not continue the map,
    ///   or a bad record in an older segment that the next does not redo). That is an
    ///   error, and nothing is cut: a record once synced is never removed.
    ///
    /// A record that does not follow the map (a gap in sequence numbers, a removed Gaussian
    /// the map does not hold, an added id it already holds) is an error; the map may then be
    /// partly replayed and should be dropped.
    pub fn replay_journal(
        &mut self,
        segments: &[PathBuf],
        tiles: &Path,
        at_torn: AtTornTail,
    ) -> Result<Replay, StoreError> {
        let mut replay = Replay::default();
        for (i, path) in segments.iter().enumerate() {
            let End::Torn(offset) = self.replay_segment(path, tiles, &mut replay)? else {
                continue;
            };
            let len = std::fs::metadata(path).map_err(io_error(path))?.len();
            let redone_next = segments
                .get(i + 1)
                .and_then(|p| first_sequence(p))
                .is_some_and(|first| first <= self.increments + 1);
            let last = i + 1 == segments.len();
            match at_torn {
                _ if redone_next => replay.failed_writes.push(FailedWrite {
                    path: path.clone(),
                    offset,
                    bytes: len - offset,
                }),
                AtTornTail::Cut if last => replay.torn = Some(cut(path, offset)?),
                AtTornTail::Stop if last => {
                    replay.torn = Some(TornTail {
                        path: path.clone(),
                        kept_bytes: offset,
                        cut_bytes: len - offset,
                    });
                }
                _ => {
                    return Err(StoreError::Invalid {
                        path: path.clone(),
                        offset: offset as usize,
                        what: "incomplete or corrupt journal record",
                    })
                }
            }
        }
        Ok(replay)
    }

    fn replay_segment(
        &mut self,
        path: &Path,
        tiles: &Path,
        replay: &mut Replay,
    ) -> Result<End, StoreError> {
        let file = File::open(path).map_err(io_error(path))?;
        let mut input = BufReader::new(file);
        let mut header = [0u8; HEADER_BYTES as usize];
        match read_full(&mut input, &mut header).map_err(io_error(path))? {
            n if n < header.len() => return Ok(End::Torn(0)),
            _ => {}
        }
        if &header[..8] != MAGIC {
            return Err(StoreError::BadMagic {
                path: path.to_path_buf(),
            });
        }
        let version = u32::from_le_bytes(header[8..].try_into().unwrap_or_default());
        if !(OLDEST_VERSION..=VERSION).contains(&version) {
            return Err(StoreError::UnsupportedVersion {
                path: path.to_path_buf(),
                version,
            });
        }
        let mut offset = HEADER_BYTES;
        loop {
            let Some(payload) = read_record(&mut input).map_err(io_error(path))? else {
                return Ok(End::Clean);
            };
            let Ok(payload) = payload else {
                match after_bad_record(path, offset, self.increments + 1)? {
                    After::Nothing => return Ok(End::Torn(offset)),
                    After::Redone(next) => {
                        replay.failed_writes.push(FailedWrite {
                            path: path.to_path_buf(),
                            offset,
                            bytes: next - offset,
                        });
                        input.seek(SeekFrom::Start(next)).map_err(io_error(path))?;
                        offset = next;
                        continue;
                    }
                    After::Later => {
                        return Err(StoreError::Invalid {
                            path: path.to_path_buf(),
                            offset: offset as usize,
                            what: "corrupt journal record with later records after it",
                        })
                    }
                }
            };
            let len = payload.len() as u64;
            let record = decode(&payload, version, path, offset)?;
            if record.sequence <= self.increments {
                replay.skipped += 1;
            } else {
                self.apply_record(record, tiles, path, offset)?;
                replay.applied += 1;
            }
            offset += 12 + len;
        }
    }

    /// Applies one record: the tiles paged before the bin, its removed ids, its Gaussians,
    /// the tiles paged after it, its counters.
    fn apply_record(
        &mut self,
        rec: Record,
        tiles: &Path,
        path: &Path,
        offset: u64,
    ) -> Result<(), StoreError> {
        let bad = |what| StoreError::Invalid {
            path: path.to_path_buf(),
            offset: offset as usize,
            what,
        };
        if rec.sequence != self.increments + 1 {
            return Err(bad("journal record out of sequence with the map"));
        }
        self.apply_paging(&rec.before, tiles)
            .map_err(|e| e.or(bad))?;
        for id in &rec.removed {
            let g = self
                .gaussians
                .remove(id)
                .ok_or_else(|| bad("removes a Gaussian the map does not hold"))?;
            let key = cell_of(g.position, self.config.cell_size);
            let gaussians = &self.gaussians;
            self.cells
                .remove_id(key, *id, |i| gaussians.get(&i).map(|g| g.confidence));
        }
        for (id, g) in rec.added {
            if id.0 >= rec.next_id || self.gaussians.contains_key(&id) {
                return Err(bad("adds an id the map holds or has not assigned"));
            }
            let key = cell_of(g.position, self.config.cell_size);
            self.cells.push(key, id, g.confidence);
            self.gaussians.insert(id, g);
        }
        self.apply_paging(&rec.after, tiles)
            .map_err(|e| e.or(bad))?;
        self.increments = rec.sequence;
        self.epoch = rec.epoch;
        self.last_bin_id = Some(rec.bin_id);
        self.next_id = rec.next_id;
        self.latest_origin = rec.latest_origin;
        Ok(())
    }
}

/// Why a record's paged tile could not be applied: a tile file that does not read, or a
/// record that does not follow the map (said by the caller, which knows where it is).
enum PagingError {
    File(StoreError),
    Record(&'static str),
}

impl PagingError {
    fn or(self, bad: impl FnOnce(&'static str) -> StoreError) -> StoreError {
        match self {
            PagingError::File(e) => e,
            PagingError::Record(what) => bad(what),
        }
    }
}

impl GlobalMap {
    /// Pages tiles in (reading their files from `tiles`) and out (dropping them from memory)
    /// as a record says.
    fn apply_paging(&mut self, events: &[PageEvent], tiles: &Path) -> Result<(), PagingError> {
        for event in events {
            match *event {
                PageEvent::In(tile, paged) => {
                    if self.paged.get(&tile) != Some(&paged) {
                        return Err(PagingError::Record(
                            "pages in a tile the map has not paged out",
                        ));
                    }
                    self.page_in(tiles, tile).map_err(PagingError::File)?;
                }
                PageEvent::Out(tile, paged) => {
                    let taken = self
                        .take_tile(tile, paged.version)
                        .map_err(PagingError::Record)?;
                    if taken.len() as u64 != paged.count {
                        return Err(PagingError::Record(
                            "pages out a tile holding another count than the record's",
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}

/// The next record's payload: `None` at the end of the input, `Some(Err(()))` for a record
/// that is incomplete or fails its checksum.
#[allow(clippy::type_complexity)]
fn read_record(input: &mut impl Read) -> std::io::Result<Option<Result<Vec<u8>, ()>>> {
    let mut len = [0u8; 4];
    match read_full(input, &mut len)? {
        0 => return Ok(None),
        4 => {}
        _ => return Ok(Some(Err(()))),
    }
    let len = u32::from_le_bytes(len) as usize;
    // Read through `take`, so a claimed length past the file's end allocates only what
    // the file holds.
    let mut payload = Vec::new();
    let got = input.take(len as u64).read_to_end(&mut payload)?;
    let mut sum = [0u8; 8];
    let sum_got = read_full(input, &mut sum)?;
    if got < len || sum_got < 8 || fnv1a(&payload) != u64::from_le_bytes(sum) {
        return Ok(Some(Err(())));
    }
    Ok(Some(Ok(payload)))
}

/// What follows the bad record at `offset` of the segment `path` ([`After`]), found by
/// looking at every later offset for a complete record (its length fits, its checksum
/// matches) whose sequence number is `expected` or later. Reads the rest of the segment
/// into memory: a failure path, bounded by the segment's size.
fn after_bad_record(path: &Path, offset: u64, expected: u64) -> Result<After, StoreError> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    let start = (offset as usize + 1).min(bytes.len());
    for at in start..bytes.len().saturating_sub(20) {
        let len = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap_or_default()) as usize;
        let Some(end) = (at + 4).checked_add(len).filter(|e| e + 8 <= bytes.len()) else {
            continue;
        };
        if len < 8 {
            continue;
        }
        let payload = &bytes[at + 4..end];
        let sequence = u64::from_le_bytes(payload[..8].try_into().unwrap_or_default());
        // Each record holds at least its 8-byte sequence number and 12 bytes of framing.
        let plausible = sequence >= expected && sequence - expected <= (bytes.len() / 20) as u64;
        let sum = u64::from_le_bytes(bytes[end..end + 8].try_into().unwrap_or_default());
        if plausible && fnv1a(payload) == sum {
            return Ok(match sequence == expected {
                true => After::Redone(at as u64),
                false => After::Later,
            });
        }
    }
    Ok(After::Nothing)
}

/// Reads until `buf` is full or the input ends; the bytes read.
fn read_full(input: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match input.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Truncates `path` to `offset` bytes (a segment with not even a whole header is removed).
fn cut(path: &Path, offset: u64) -> Result<TornTail, StoreError> {
    let len = std::fs::metadata(path).map_err(io_error(path))?.len();
    if offset == 0 {
        std::fs::remove_file(path).map_err(io_error(path))?;
    } else {
        let file = OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(io_error(path))?;
        file.set_len(offset).map_err(io_error(path))?;
        file.sync_all().map_err(io_error(path))?;
    }
    Ok(TornTail {
        path: path.to_path_buf(),
        kept_bytes: offset,
        cut_bytes: len - offset,
    })
}
