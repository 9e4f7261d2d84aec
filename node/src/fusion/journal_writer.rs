//! Appending to the global map's journal ([`super::journal`] has the format) so that a
//! failed write never leaves the journal damaged and a failed sync is never taken for a
//! durable record.
//!
//! The writer keeps every record appended since the last successful sync in memory until
//! it is synced. A write or a sync that fails abandons the open segment: it is cut back to
//! its synced length (best effort) and closed, and the next attempt writes the kept records
//! again into a new segment, named after the first of them, and syncs that. A failed fsync
//! is not retried on the same file: on Linux the failed pages may be marked clean and a
//! second fsync report success for data that is not on disk. Whatever the failed segment's
//! tail holds afterwards (nothing, part of a record, or records the new segment repeats),
//! replay skips it ([`super::GlobalMap::replay_journal`]), so a record that was ever
//! reported durable is never cut and no record is applied twice.
//!
//! Segments are created with `create_new`, so the writer never truncates a file it did not
//! make in this run; the one exception is a segment it is told holds no record
//! ([`JournalWriter::adopt`]: a header-only segment a crash left, which a restarting node
//! appends to rather than leaving beside a new one).

use std::fs::{File, OpenOptions};
use std::io::{ErrorKind, Write};
use std::path::{Path, PathBuf};

use super::journal::{encode, segment_path, HEADER, HEADER_BYTES};
use super::tiles::PageEvent;
use super::{GlobalMap, Increment, StoreError};

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> StoreError + '_ {
    move |source| StoreError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The file operations a segment needs: a seam so that tests can fail them as a full disk
/// or a failing device does ([`JournalWriter::with_files`]).
pub trait SegmentFile: Send + Sync {
    /// Appends `bytes` at the end of the file.
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()>;
    /// Makes the written bytes durable (fdatasync).
    fn sync_data(&mut self) -> std::io::Result<()>;
    /// Cuts the file to `len` bytes.
    fn set_len(&mut self, len: u64) -> std::io::Result<()>;
}

impl SegmentFile for File {
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        Write::write_all(self, bytes)
    }

    fn sync_data(&mut self) -> std::io::Result<()> {
        File::sync_data(self)
    }

    fn set_len(&mut self, len: u64) -> std::io::Result<()> {
        File::set_len(self, len)
    }
}

/// How a segment file is opened: a new file (`create_new`), or, with `reuse`, a file of
/// the writer's own that holds no record, emptied.
pub type OpenSegment =
    Box<dyn FnMut(&Path, bool) -> std::io::Result<Box<dyn SegmentFile>> + Send + Sync>;

/// Opens segment files on the file system ([`OpenSegment`]).
pub fn open_on_disk(path: &Path, reuse: bool) -> std::io::Result<Box<dyn SegmentFile>> {
    let mut options = OpenOptions::new();
    options.write(true);
    match reuse {
        true => options.truncate(true),
        false => options.create_new(true),
    };
    Ok(Box::new(options.open(path)?))
}

/// The open segment.
struct Open {
    file: Box<dyn SegmentFile>,
    path: PathBuf,
    /// Bytes of the file known durable (the header and every synced record).
    synced: u64,
}

/// Appends the map's changes to the journal, one record per bin (the module doc says how
/// failures are survived).
pub struct JournalWriter {
    dir: PathBuf,
    open: Option<Open>,
    /// Every record appended since the last successful sync, encoded.
    unsynced: Vec<u8>,
    /// The sequence number of the first of them.
    unsynced_first: u64,
    /// Records among them.
    unsynced_records: u64,
    /// Bytes of `unsynced` written into the open segment.
    in_file: usize,
    /// A segment of the writer's own that holds no record: reused when the next segment
    /// has its name.
    reusable: Option<PathBuf>,
    /// Whether the folder's own entry is known durable in its parent.
    dir_synced: bool,
    files: OpenSegment,
}

impl std::fmt::Debug for JournalWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JournalWriter")
            .field("dir", &self.dir)
            .field("open", &self.open.as_ref().map(|o| &o.path))
            .field("unsynced_records", &self.unsynced_records)
            .finish_non_exhaustive()
    }
}

impl JournalWriter {
    /// A writer into the folder `dir` (created with the first segment). It opens a new
    /// segment for its first record, so it never appends to a segment a crash may have torn.
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self::with_files(dir, Box::new(open_on_disk))
    }

    /// A writer whose segment files are opened by `files` (tests put failing files there).
    pub fn with_files(dir: impl Into<PathBuf>, files: OpenSegment) -> Self {
        Self {
            dir: dir.into(),
            open: None,
            unsynced: Vec::new(),
            unsynced_first: 0,
            unsynced_records: 0,
            in_file: 0,
            reusable: None,
            dir_synced: false,
            files,
        }
    }

    /// Takes `segment`, which holds only its header (a crash left it), as the writer's own:
    /// when the next record opens a segment of that name, it is reused instead of failing
    /// as an existing file.
    pub fn adopt(&mut self, segment: PathBuf) {
        self.reusable = Some(segment);
    }

    /// The journal's folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Bytes in the open segment, durable or not (0 when none is open).
    pub fn segment_bytes(&self) -> u64 {
        self.open
            .as_ref()
            .map_or(0, |o| o.synced + self.in_file as u64)
    }

    /// Records appended and not yet durable.
    pub fn unsynced_records(&self) -> u64 {
        self.unsynced_records
    }

    /// Appends the record of `inc`, which `map` has just taken in (its counters are read
    /// after the bin), with the tiles paged in `before` the bin and out `after` it, and
    /// writes it ([`JournalWriter::write`]). The record is kept until a sync succeeds, so
    /// when the write fails it is written again by the next write or sync. Returns the
    /// record's size in bytes, or the write's error.
    pub fn append(
        &mut self,
        map: &GlobalMap,
        inc: &Increment,
        before: &[PageEvent],
        after: &[PageEvent],
    ) -> Result<u64, StoreError> {
        let bytes = self.push(map, inc, before, after);
        self.write()?;
        Ok(bytes)
    }

    /// Encodes the record of `inc` (see [`JournalWriter::append`]) and keeps it for the
    /// next write, without writing it; returns its size in bytes.
    pub fn push(
        &mut self,
        map: &GlobalMap,
        inc: &Increment,
        before: &[PageEvent],
        after: &[PageEvent],
    ) -> u64 {
        let record = encode(map, inc, before, after);
        if self.unsynced_records == 0 {
            self.unsynced_first = map.increments();
        }
        self.unsynced.extend_from_slice(&record);
        self.unsynced_records += 1;
        record.len() as u64
    }

    /// Writes every kept record not yet in the open segment, opening a segment first when
    /// none is open. On a failure the segment is abandoned (the module doc) and the records
    /// stay kept.
    pub fn write(&mut self) -> Result<(), StoreError> {
        if self.in_file == self.unsynced.len() {
            return Ok(());
        }
        if self.open.is_none() {
            self.open_segment(self.unsynced_first)?;
        }
        let Some(open) = &mut self.open else {
            unreachable!("a segment was opened above")
        };
        match open.file.write_all(&self.unsynced[self.in_file..]) {
            Ok(()) => {
                self.in_file = self.unsynced.len();
                Ok(())
            }
            Err(e) => {
                let e = io_error(&open.path)(e);
                self.abandon();
                Err(e)
            }
        }
    }

    /// Makes every record appended so far durable: writes what is not yet written, then
    /// fdatasyncs the open segment. On a failure the segment is abandoned and the records
    /// stay kept, to be written to a new segment by the next attempt.
    pub fn sync(&mut self) -> Result<(), StoreError> {
        self.write()?;
        if self.unsynced_records == 0 {
            return Ok(());
        }
        let Some(open) = &mut self.open else {
            unreachable!("write() left a segment open")
        };
        match open.file.sync_data() {
            Ok(()) => {
                open.synced += self.unsynced.len() as u64;
                self.unsynced.clear();
                self.unsynced_records = 0;
                self.in_file = 0;
                Ok(())
            }
            Err(e) => {
                let e = io_error(&open.path)(e);
                self.abandon();
                Err(e)
            }
        }
    }

    /// Syncs and closes the open segment; returns its path (`None` when none was open).
    /// The next record opens a new segment.
    pub fn close_segment(&mut self) -> Result<Option<PathBuf>, StoreError> {
        self.sync()?;
        Ok(self.open.take().map(|o| o.path))
    }

    /// Gives up the open segment after a failed write or sync: cuts it back to its durable
    /// bytes where the file system lets it, and closes it. A segment holding no durable
    /// record stays the writer's to reuse.
    fn abandon(&mut self) {
        if let Some(mut open) = self.open.take() {
            let _ = open.file.set_len(open.synced);
            if open.synced <= HEADER_BYTES {
                self.reusable = Some(open.path);
            }
        }
        self.in_file = 0;
    }

    fn open_segment(&mut self, first_sequence: u64) -> Result<(), StoreError> {
        self.make_dir()?;
        let path = segment_path(&self.dir, first_sequence);
        let reuse = self.reusable.as_ref() == Some(&path);
        let mut file = match (self.files)(&path, reuse) {
            Ok(f) => f,
            Err(e) if e.kind() == ErrorKind::AlreadyExists => {
                return Err(StoreError::Invalid {
                    path,
                    offset: 0,
                    what: "a journal segment of this name already exists: \
                           another writer is using the folder",
                })
            }
            Err(e) => return Err(io_error(&path)(e)),
        };
        // From here the file is the writer's: a failure leaves it to be reused.
        self.reusable = Some(path.clone());
        file.write_all(&HEADER).map_err(io_error(&path))?;
        file.sync_data().map_err(io_error(&path))?;
        // The new name must survive a crash too.
        sync_dir(&self.dir)?;
        self.reusable = None;
        self.open = Some(Open {
            file,
            path,
            synced: HEADER_BYTES,
        });
        Ok(())
    }

    /// Creates the journal's folder and makes its entry durable in its parent, once.
    fn make_dir(&mut self) -> Result<(), StoreError> {
        if !self.dir_synced {
            create_dir_durably(&self.dir)?;
            self.dir_synced = true;
        }
        Ok(())
    }
}

/// Syncs the folder `dir`, so the names created in it survive a power cut.
fn sync_dir(dir: &Path) -> Result<(), StoreError> {
    File::open(dir)
        .and_then(|d| d.sync_all())
        .map_err(io_error(dir))
}

/// Creates `dir` (and its missing parents) and syncs each parent that gained an entry, so a
/// new folder survives a power cut as the files in it do.
pub fn create_dir_durably(dir: &Path) -> Result<(), StoreError> {
    if dir.is_dir() {
        return Ok(());
    }
    if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
        create_dir_durably(parent)?;
    }
    match std::fs::create_dir(dir) {
        Ok(()) => {}
        Err(e) if e.kind() == ErrorKind::AlreadyExists => return Ok(()),
        Err(e) => return Err(io_error(dir)(e)),
    }
    match dir.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(parent) => sync_dir(parent),
        None => sync_dir(Path::new(".")),
    }
}
