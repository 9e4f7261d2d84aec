//! Saving the global map to a file and restoring it, so a restarted node continues with
//! the same Gaussians and ids it had published.
//!
//! Format (all little endian): magic `SSGMAP\0\n`, version u32 (4), cell size f64, opacity
//! floor f32, budget u64, keep range f32 and keep confidence f32 (from version 3; a version-2
//! file has neither and gets [`super::Keep::default`]), tile side f64 (from version 4;
//! older files get the default), next id u64, increments u64 (the sequence number of the
//! last published increment), epoch u64 (times resumed), last bin flag u8 + id u64, latest
//! origin flag u8 + 3 x f64, the paged-out tiles (from version 4: count u64, then per tile x
//! i64, y i64, file version u64, Gaussian count u64, in tile order), count u64 of the
//! Gaussians in memory, then per Gaussian: id u64, bin id u64, position 3 x f64, log scale
//! 3 x f32, rotation 4 x f32 (x, y, z, w), opacity f32, colour 3 x f32, confidence f32;
//! last an FNV-1a 64 checksum (u64) of every byte before it. Version 1 (without increments
//! and epoch) is not read: its sequence numbers cannot be continued. Files are replaced
//! atomically ([`renderer::atomic`]: temporary sibling, fsync, rename, fsync of the folder),
//! so a crash leaves the old file whole.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use glam::{DVec3, Quat, Vec3};
use imbl::OrdMap;

use super::{
    FusionConfig, GaussianId, GlobalMap, Keep, PagedTile, StoredMap, TileKey, WorldGaussian,
};

const MAGIC: &[u8; 8] = b"SSGMAP\0\n";
const VERSION: u32 = 4;
/// The oldest version still read (without the keep rule).
const OLDEST_VERSION: u32 = 2;
/// Bytes per stored Gaussian.
pub(super) const RECORD_BYTES: usize = 88;

/// Why a map could not be saved or restored. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// Reading or writing failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The system error.
        source: std::io::Error,
    },
    /// The file does not start with the map magic.
    #[error("{path}: not a StereoSplat global map file (bad magic)")]
    BadMagic {
        /// The file.
        path: PathBuf,
    },
    /// The file's format version is not one this build reads.
    #[error("{path}: unsupported global map version {version} (this build reads {VERSION})")]
    UnsupportedVersion {
        /// The file.
        path: PathBuf,
        /// The version found.
        version: u32,
    },
    /// The file ends early.
    #[error("{path}: truncated at byte {offset} (needs {needed} more bytes)")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Where the missing data starts.
        offset: usize,
        /// How many bytes were wanted there.
        needed: usize,
    },
    /// The checksum does not match the contents.
    #[error("{path}: checksum mismatch (file corrupt)")]
    Checksum {
        /// The file.
        path: PathBuf,
    },
    /// A field holds a value the map cannot hold.
    #[error("{path}: byte {offset}: {what}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Where the record or field starts.
        offset: usize,
        /// What is wrong.
        what: &'static str,
    },
}

/// Records a file write hands to the writer at once ([`StoredMap::write_to`]).
const WRITE_CHUNK: usize = 4096;

/// FNV-1a's starting state.
const FNV_START: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a, 64 bit: a checksum that catches flipped and truncated bytes.
pub(super) fn fnv1a(bytes: &[u8]) -> u64 {
    fnv1a_from(FNV_START, bytes)
}

/// FNV-1a continued from state `h` over `bytes` (a checksum computed piece by piece).
fn fnv1a_from(h: u64, bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(h, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

impl GlobalMap {
    /// The map in the file format described in the module doc.
    pub fn to_bytes(&self) -> Vec<u8> {
        self.stored().to_bytes()
    }

    /// The size of the map's file ([`GlobalMap::to_bytes`]) in bytes, without writing it.
    pub fn stored_bytes(&self) -> u64 {
        file_bytes(self.paged.len(), self.len())
    }

    /// Writes the map to `path` atomically ([`StoredMap::save`]); returns the bytes written.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<u64, StoreError> {
        self.stored().save(path)
    }

    /// Reads a map written by [`GlobalMap::save`].
    pub fn load(path: impl AsRef<Path>) -> Result<GlobalMap, StoreError> {
        let path = path.as_ref();
        // The file's bytes are dropped before the map's cell index is built, so a load
        // holds at most the file and the Gaussians at once, not the whole map beside them.
        let stored = {
            let bytes = std::fs::read(path).map_err(|source| StoreError::Io {
                path: path.to_path_buf(),
                source,
            })?;
            parse(&bytes, path)?
        };
        Ok(GlobalMap::from_parts(stored))
    }

    /// Parses the file format; `path` only names the source in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<GlobalMap, StoreError> {
        parse(bytes, path).map(GlobalMap::from_parts)
    }
}

/// The size in bytes of a map file with `paged` paged-out tiles and `gaussians` records:
/// the header (122 bytes with the tile count), 32 bytes per paged tile, the records and the
/// checksum (8).
fn file_bytes(paged: usize, gaussians: usize) -> u64 {
    130 + 32 * paged as u64 + (gaussians * RECORD_BYTES) as u64
}

impl StoredMap {
    /// The map in the file format described in the module doc.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(self.stored_bytes() as usize);
        self.write_to(&mut b)
            .expect("writing into a Vec cannot fail");
        b
    }

    /// Writes the map in the file format described in the module doc into `w`, a bounded
    /// chunk of records at a time, so saving a large map holds no second copy of it in
    /// memory; returns the bytes written.
    pub fn write_to(&self, w: &mut impl Write) -> std::io::Result<u64> {
        let mut b = Vec::with_capacity(WRITE_CHUNK * RECORD_BYTES);
        b.extend_from_slice(MAGIC);
        b.extend_from_slice(&VERSION.to_le_bytes());
        b.extend_from_slice(&self.config.cell_size.to_le_bytes());
        b.extend_from_slice(&self.config.opacity_floor.to_le_bytes());
        b.extend_from_slice(&(self.config.max_gaussians as u64).to_le_bytes());
        b.extend_from_slice(&self.config.keep.max_range_m.to_le_bytes());
        b.extend_from_slice(&self.config.keep.min_confidence.to_le_bytes());
        b.extend_from_slice(&self.config.tile_m.to_le_bytes());
        b.extend_from_slice(&self.next_id.to_le_bytes());
        b.extend_from_slice(&self.increments.to_le_bytes());
        b.extend_from_slice(&self.epoch.to_le_bytes());
        b.push(u8::from(self.last_bin_id.is_some()));
        b.extend_from_slice(&self.last_bin_id.unwrap_or(0).to_le_bytes());
        b.push(u8::from(self.latest_origin.is_some()));
        put_f64s(
            &mut b,
            &self.latest_origin.unwrap_or(DVec3::ZERO).to_array(),
        );
        b.extend_from_slice(&(self.paged.len() as u64).to_le_bytes());
        for (tile, p) in &self.paged {
            for v in [tile.0 as u64, tile.1 as u64, p.version, p.count] {
                b.extend_from_slice(&v.to_le_bytes());
            }
        }
        b.extend_from_slice(&(self.gaussians.len() as u64).to_le_bytes());
        let mut sum = FNV_START;
        let mut written = 0u64;
        let mut flush = |b: &mut Vec<u8>, sum: &mut u64| -> std::io::Result<()> {
            *sum = fnv1a_from(*sum, b);
            w.write_all(b)?;
            written += b.len() as u64;
            b.clear();
            Ok(())
        };
        for (&id, g) in self.gaussians.iter() {
            put_gaussian(&mut b, id, g);
            if b.len() >= WRITE_CHUNK * RECORD_BYTES {
                flush(&mut b, &mut sum)?;
            }
        }
        flush(&mut b, &mut sum)?;
        w.write_all(&sum.to_le_bytes())?;
        Ok(written + 8)
    }

    /// The size of the map's file ([`StoredMap::to_bytes`]) in bytes, without writing it.
    pub fn stored_bytes(&self) -> u64 {
        file_bytes(self.paged.len(), self.gaussians.len())
    }

    /// The tiles the map has paged out, with their file versions and counts.
    pub fn paged_tiles(&self) -> &BTreeMap<TileKey, PagedTile> {
        &self.paged
    }

    /// The sequence number of the map's last increment.
    pub fn increments(&self) -> u64 {
        self.increments
    }

    /// Writes the map to `path` atomically (see the module doc): a crash at any moment
    /// leaves the previous file or the new one, whole. Returns the bytes written.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<u64, StoreError> {
        let path = path.as_ref();
        let mut written = 0;
        renderer::atomic::write_atomic(path, |w| {
            written = self.write_to(w)?;
            Ok(())
        })
        .map_err(|source: std::io::Error| StoreError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Ok(written)
    }
}

/// The stored parts of a map in the file format (the module doc); `path` only names the
/// source in errors.
fn parse(bytes: &[u8], path: &Path) -> Result<StoredMap, StoreError> {
    let mut r = Reader {
        bytes,
        pos: 0,
        path,
    };
    if r.take(MAGIC.len())? != MAGIC {
        return Err(StoreError::BadMagic {
            path: path.to_path_buf(),
        });
    }
    let version = r.u32()?;
    if !(OLDEST_VERSION..=VERSION).contains(&version) {
        return Err(StoreError::UnsupportedVersion {
            path: path.to_path_buf(),
            version,
        });
    }
    if bytes.len() < r.pos + 8 {
        return Err(r.truncated(8));
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    if fnv1a(body) != u64::from_le_bytes(sum.try_into().unwrap_or_default()) {
        return Err(StoreError::Checksum {
            path: path.to_path_buf(),
        });
    }
    r.bytes = body;
    let at = r.pos;
    let config = FusionConfig {
        cell_size: r.f64()?,
        opacity_floor: r.f32()?,
        max_gaussians: usize::try_from(r.u64()?).unwrap_or(usize::MAX),
        keep: match version {
            2 => Keep::default(),
            _ => Keep {
                max_range_m: r.f32()?,
                min_confidence: r.f32()?,
            },
        },
        tile_m: match version {
            2 | 3 => FusionConfig::default().tile_m,
            _ => r.f64()?,
        },
    };
    config
        .validate()
        .map_err(|_| r.invalid(at, "settings out of range"))?;
    let next_id = r.u64()?;
    let increments = r.u64()?;
    let epoch = r.u64()?;
    let last_bin_id = r.flagged(|r| r.u64())?;
    let latest_origin = r.flagged(|r| r.f64s::<3>().map(DVec3::from_array))?;
    if latest_origin.is_some_and(|o| !o.is_finite()) {
        return Err(r.invalid(r.pos - 24, "latest origin is not finite"));
    }
    let mut paged = BTreeMap::new();
    if version >= 4 {
        let tiles = r.u64()?;
        if tiles > (r.bytes.len() / 32) as u64 {
            return Err(r.invalid(r.pos - 8, "paged tile count does not fit the file"));
        }
        for _ in 0..tiles {
            let at = r.pos;
            let tile = (r.u64()? as i64, r.u64()? as i64);
            let p = PagedTile {
                version: r.u64()?,
                count: r.u64()?,
            };
            if paged
                .last_key_value()
                .is_some_and(|(last, _)| *last >= tile)
                || p.version > increments
            {
                return Err(r.invalid(at, "paged tiles out of order or from the future"));
            }
            paged.insert(tile, p);
        }
    }
    let count = r.u64()?;
    let left = (r.bytes.len() - r.pos) as u64;
    if count.checked_mul(RECORD_BYTES as u64) != Some(left) {
        return Err(r.invalid(r.pos - 8, "count does not match the file length"));
    }
    let mut gaussians = OrdMap::new();
    let mut previous: Option<u64> = None;
    for _ in 0..count {
        let at = r.pos;
        let (id, g) = r.gaussian()?;
        if previous.is_some_and(|p| id.0 <= p) || id.0 >= next_id {
            return Err(r.invalid(at, "ids not increasing or not below the next id"));
        }
        previous = Some(id.0);
        gaussians.insert(id, g);
    }
    Ok(StoredMap {
        config,
        gaussians,
        paged,
        next_id,
        last_bin_id,
        latest_origin,
        increments,
        epoch,
    })
}

/// Appends one stored Gaussian ([`RECORD_BYTES`] bytes: id, bin id, position, log scale,
/// rotation, opacity, colour, confidence).
pub(super) fn put_gaussian(b: &mut Vec<u8>, id: GaussianId, g: &WorldGaussian) {
    b.extend_from_slice(&id.0.to_le_bytes());
    b.extend_from_slice(&g.bin_id.to_le_bytes());
    put_f64s(b, &g.position.to_array());
    put_f32s(b, &g.log_scale.to_array());
    put_f32s(b, &g.rotation.to_array());
    put_f32s(b, &[g.opacity]);
    put_f32s(b, &g.color.to_array());
    put_f32s(b, &[g.confidence]);
}

pub(super) fn put_f64s(b: &mut Vec<u8>, v: &[f64]) {
    v.iter().for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
}

fn put_f32s(b: &mut Vec<u8>, v: &[f32]) {
    v.iter().for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
}

/// A cursor over the file's bytes that turns running out into [`StoreError::Truncated`].
pub(super) struct Reader<'a> {
    /// The bytes read.
    pub bytes: &'a [u8],
    /// Where the next read starts.
    pub pos: usize,
    /// The file, named in errors.
    pub path: &'a Path,
}

impl<'a> Reader<'a> {
    /// One Gaussian as [`put_gaussian`] writes it; a NaN or infinite field is an error, and
    /// opacity and confidence are clamped to [0, 1] (the map's own are; a file's need not
    /// be). The base, the journal and the tiles all read Gaussians here.
    pub fn gaussian(&mut self) -> Result<(GaussianId, WorldGaussian), StoreError> {
        let at = self.pos;
        let id = GaussianId(self.u64()?);
        let g = WorldGaussian {
            bin_id: self.u64()?,
            position: DVec3::from_array(self.f64s()?),
            log_scale: Vec3::from_array(self.f32s()?),
            rotation: Quat::from_array(self.f32s()?),
            opacity: self.f32()?,
            color: Vec3::from_array(self.f32s()?),
            confidence: self.f32()?,
        };
        if !g.is_finite() {
            return Err(self.invalid(at, "Gaussian with a NaN or infinite field"));
        }
        let g = WorldGaussian {
            opacity: g.opacity.clamp(0.0, 1.0),
            confidence: g.confidence.clamp(0.0, 1.0),
            ..g
        };
        Ok((id, g))
    }

    fn truncated(&self, needed: usize) -> StoreError {
        StoreError::Truncated {
            path: self.path.to_path_buf(),
            offset: self.pos,
            needed,
        }
    }

    pub fn invalid(&self, offset: usize, what: &'static str) -> StoreError {
        StoreError::Invalid {
            path: self.path.to_path_buf(),
            offset,
            what,
        }
    }

    pub fn take(&mut self, n: usize) -> Result<&'a [u8], StoreError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| self.truncated(n))?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    pub fn array<const N: usize>(&mut self) -> Result<[u8; N], StoreError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }

    pub fn u32(&mut self) -> Result<u32, StoreError> {
        self.array().map(u32::from_le_bytes)
    }

    pub fn u64(&mut self) -> Result<u64, StoreError> {
        self.array().map(u64::from_le_bytes)
    }

    pub fn f32(&mut self) -> Result<f32, StoreError> {
        self.array().map(f32::from_le_bytes)
    }

    pub fn f64(&mut self) -> Result<f64, StoreError> {
        self.array().map(f64::from_le_bytes)
    }

    pub fn f32s<const N: usize>(&mut self) -> Result<[f32; N], StoreError> {
        let mut a = [0.0; N];
        for x in &mut a {
            *x = self.f32()?;
        }
        Ok(a)
    }

    pub fn f64s<const N: usize>(&mut self) -> Result<[f64; N], StoreError> {
        let mut a = [0.0; N];
        for x in &mut a {
            *x = self.f64()?;
        }
        Ok(a)
    }

    /// A flag byte (0 or 1) then a value that is always present; `None` when the flag is 0.
    pub fn flagged<T>(
        &mut self,
        read: impl FnOnce(&mut Self) -> Result<T, StoreError>,
    ) -> Result<Option<T>, StoreError> {
        let at = self.pos;
        let flag = self.array::<1>()?[0];
        let value = read(self)?;
        match flag {
            0 => Ok(None),
            1 => Ok(Some(value)),
            _ => Err(self.invalid(at, "flag byte is neither 0 nor 1")),
        }
    }
}
