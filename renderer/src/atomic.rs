//! Replacing a file so that a crash (a kill, a power cut) at any moment leaves either the
//! old file or the complete new one, never a part of the new one.
//!
//! The content goes to a temporary sibling `<name>.<process>-<write>.tmp` (same folder, so
//! the same file system), which is flushed and synced to disk, then renamed over the target
//! (atomic on POSIX file systems), and the folder is synced so the rename itself is durable.
//! The sibling is unique to the write, so writers of one file at once (threads, or parallel
//! `synth` runs sharing a KITTI-360 root's calibration) never write into the same temporary
//! file, and a reader sees one whole version. It is created with `create_new`, so a name
//! someone else made first (a file, or a link pointing elsewhere) is never written through. Every exporter of the workspace (PLY, PNG, the
//! node's map files, the KITTI-360 text files) writes through here.

use std::ffi::OsString;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The temporary sibling one write to `path` goes through: `path` with
/// `.<process id>-<write number>.tmp` appended.
fn temp_path(path: &Path) -> PathBuf {
    static WRITES: AtomicU64 = AtomicU64::new(0);
    let write = WRITES.fetch_add(1, Ordering::Relaxed);
    let mut name = OsString::from(path.as_os_str());
    name.push(format!(".{}-{write}.tmp", std::process::id()));
    PathBuf::from(name)
}

/// Replaces (or creates) the file at `path` with what `write` writes into the buffered
/// writer it is given, atomically as the module doc describes. When `write` or any step
/// fails, the target is untouched, the temporary file is removed and the error returned.
pub fn write_atomic<E: From<io::Error>>(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<(), E>,
) -> Result<(), E> {
    let (tmp, file) = create_temp(path)?;
    let result = (|| {
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(io::IntoInnerError::into_error)?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&tmp, path)?;
        sync_folder(path)?;
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Creates a new temporary sibling of `path` ([`temp_path`]) with `create_new`: a file or a
/// link already at that name (left by another process, or planted there) is never opened
/// or followed; the next name is tried instead, a few times.
fn create_temp(path: &Path) -> io::Result<(PathBuf, File)> {
    let mut tries = 0;
    loop {
        let tmp = temp_path(path);
        match File::options().write(true).create_new(true).open(&tmp) {
            Ok(file) => return Ok((tmp, file)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists && tries < 8 => tries += 1,
            Err(e) => return Err(e),
        }
    }
}

/// [`write_atomic`] of a byte buffer.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}

/// Syncs the folder holding `path`, so a rename into it survives a power cut. Where folders
/// cannot be opened for syncing (not Unix), renames are left to the file system.
fn sync_folder(path: &Path) -> io::Result<()> {
    if !cfg!(unix) {
        return Ok(());
    }
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    File::open(folder)?.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether a temporary sibling of `path` (of any write) is left in its folder.
    fn temporary_left(path: &Path) -> bool {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        std::fs::read_dir(path.parent().unwrap()).unwrap().any(|e| {
            let other = e.unwrap().file_name().to_string_lossy().into_owned();
            other.starts_with(&format!("{name}.")) && other.ends_with(".tmp")
        })
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("renderer-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let path = scratch("kept.bin");
        write_bytes_atomic(&path, b"old content").unwrap();
        let failed: io::Result<()> = write_atomic(&path, |w| {
            w.write_all(b"half of the new")?;
            Err(io::Error::other("killed mid-write"))
        });
        assert_eq!(failed.unwrap_err().to_string(), "killed mid-write");
        assert_eq!(std::fs::read(&path).unwrap(), b"old content");
        assert!(!temporary_left(&path));
        write_bytes_atomic(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert!(!temporary_left(&path));
    }

    #[cfg(unix)]
    #[test]
    fn a_link_planted_at_the_next_temporary_name_is_not_written_through() {
        let path = scratch("planted.bin");
        let victim = scratch("victim.bin");
        std::fs::write(&victim, b"not yours").unwrap();
        // The name the next write would take (writes are numbered per process), planted as
        // a link to another file.
        let next = temp_path(&path);
        let number: u64 = next
            .to_string_lossy()
            .rsplit('-')
            .next()
            .unwrap()
            .trim_end_matches(".tmp")
            .parse()
            .unwrap();
        for k in number + 1..number + 4 {
            let name = format!("{}.{}-{k}.tmp", path.display(), std::process::id());
            std::os::unix::fs::symlink(&victim, name).unwrap();
        }
        write_bytes_atomic(&path, b"mine").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"mine");
        assert_eq!(std::fs::read(&victim).unwrap(), b"not yours");
    }

    #[test]
    fn a_missing_folder_is_an_error_and_writes_nothing() {
        let path = scratch("no/such/folder/file.bin");
        assert!(write_bytes_atomic(&path, b"x").is_err());
        assert!(!path.exists());
    }
}
