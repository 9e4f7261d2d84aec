//! Gaussian sets as PLY files, in the layout of the original 3D Gaussian splatting code, so
//! maps open in the common splat viewers and maps trained elsewhere load here.
//!
//! One `vertex` element, one record per Gaussian, float properties in this order:
//! `x y z nx ny nz f_dc_0 f_dc_1 f_dc_2 opacity scale_0 scale_1 scale_2 rot_0 rot_1 rot_2
//! rot_3 confidence`, with the conventions of that code:
//!
//! * `f_dc = (rgb - 0.5) / C0` ([`SH_C0`]): the degree-0 spherical-harmonic coefficient whose
//!   evaluation is our colour;
//! * `opacity` is the logit of our opacity, which is first clamped to
//!   `[OPACITY_EPS, 1 - OPACITY_EPS]` ([`OPACITY_EPS`]) so that 0 and 1 stay finite;
//! * `scale_*` are natural logs of standard deviations (our `log_scales` as they are);
//! * `rot_0..3` is the quaternion in the order (w, x, y, z), not glam's (x, y, z, w);
//! * normals are written as 0 (viewers expect the properties, nothing uses them);
//! * `confidence` is our extra property; readers that do not know it ignore it.
//!
//! The reader accepts `binary_little_endian 1.0` and `ascii 1.0` files with any elements
//! besides `vertex` (skipped by their declared sizes), scalar properties of any PLY type
//! (converted to `f32`), and unknown extra properties (ignored, e.g. the `f_rest_*` of a
//! degree-3 file). `confidence` is optional and defaults to 1. Integer-typed properties are
//! converted by value (no rescaling of `uchar` to [0, 1]). List properties are allowed in
//! other elements, before or after `vertex` (each record's lists are walked to skip it),
//! but not in `vertex`. Rotations are read as stored: not normalised (trainers write raw
//! quaternions; the rasterizers normalise). It never panics and never allocates much more
//! than the data actually present, whatever the header declares.

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Write};
use std::path::Path;

use crate::gaussians::{GaussianSet, LengthMismatch};

mod body;
mod header;

use body::read_body;
use header::read_header;

/// Zeroth-order real spherical-harmonic basis constant, `1 / (2 sqrt(pi))`: colour is
/// `0.5 + SH_C0 * f_dc` in the 3DGS convention.
pub const SH_C0: f64 = 0.282_094_791_773_878_14;

/// Opacities are clamped to `[OPACITY_EPS, 1 - OPACITY_EPS]` before the logit is written, so
/// opacity 0 and 1 are stored as finite numbers (about -13.8 and 13.8) and read back as
/// `1e-6` and `1 - 1e-6`.
pub const OPACITY_EPS: f64 = 1e-6;

/// The stored form of an opacity: its logit, the opacity first clamped to
/// `[OPACITY_EPS, 1 - OPACITY_EPS]` so 0 and 1 stay finite. Shared by every format that
/// follows the 3DGS convention (PLY, the node's PointCloud2).
pub fn opacity_logit(opacity: f32) -> f64 {
    let p = (opacity as f64).clamp(OPACITY_EPS, 1.0 - OPACITY_EPS);
    (p / (1.0 - p)).ln()
}

/// The opacity a stored logit stands for (the inverse of [`opacity_logit`]).
pub fn opacity_from_logit(logit: f64) -> f32 {
    (1.0 / (1.0 + (-logit).exp())) as f32
}

/// The header may be at most this long; a stream without `end_header` is refused here rather
/// than read to its end.
const MAX_HEADER_BYTES: u64 = 64 * 1024;

/// Records are read (and written) in chunks of about this many bytes.
const CHUNK_BYTES: usize = 1 << 20;

/// An ascii token longer than this is malformed (the longest honest number is ~30 chars).
const MAX_TOKEN_BYTES: usize = 128;

/// Everything that can go wrong reading or writing a PLY file.
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    /// The underlying reader or writer failed.
    #[error("PLY I/O error: {0}")]
    Io(#[from] io::Error),
    /// The first line is not `ply`.
    #[error("not a PLY file (the first line is not `ply`)")]
    NotPly,
    /// A format this reader does not handle (big endian, a version other than 1.0), or a
    /// layout it does not (a list property in the vertex element).
    #[error("unsupported PLY format: {0}")]
    UnsupportedFormat(String),
    /// A malformed header line (1-based line number).
    #[error("bad PLY header at line {line}: {reason}")]
    BadHeader {
        /// Line number, 1-based.
        line: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// The file has no element of this name (`vertex`).
    #[error("PLY file has no `{0}` element")]
    MissingElement(String),
    /// The vertex element lacks a property the Gaussians need.
    #[error("PLY vertex element lacks the `{0}` property")]
    MissingProperty(String),
    /// The binary data ends before the records the header declares.
    #[error("PLY data truncated: the header declares at least {expected_bytes} bytes of data, the file holds {got_bytes}")]
    Truncated {
        /// Data bytes (after the header) needed up to the end of the vertex element; a lower
        /// bound when an element before it has list properties.
        expected_bytes: u64,
        /// Data bytes actually present.
        got_bytes: u64,
    },
    /// An element declares more records than could fit the file (checked before anything is
    /// allocated), or than any file could hold.
    #[error("PLY element `{element}` declares {count} records, at least {needed_bytes} bytes of data up to its end, {}", available_text(*.available_bytes))]
    TooLarge {
        /// The element's name.
        element: String,
        /// Its declared record count.
        count: u64,
        /// Data bytes needed up to the end of this element (lower bound).
        needed_bytes: u128,
        /// Data bytes the file holds, when known.
        available_bytes: Option<u64>,
    },
    /// A malformed record: an ascii token that is not a number, a negative list length,
    /// an ascii file that ends early.
    #[error("bad PLY data in element `{element}`, record {record}: {reason}")]
    BadData {
        /// The element's name.
        element: String,
        /// Record index, 0-based.
        record: u64,
        /// What is wrong with it.
        reason: String,
    },
    /// The set to write has arrays of different lengths.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
}

fn available_text(available: Option<u64>) -> String {
    match available {
        Some(a) => format!("but the file holds {a}"),
        None => "more than any file can hold".to_owned(),
    }
}

/// Writes `set` as a binary little-endian 3DGS PLY (see the module documentation for the
/// layout and conversions). Errors when the set's arrays differ in length or `w` fails.
pub fn write_ply(set: &GaussianSet, mut w: impl Write) -> Result<(), PlyError> {
    set.check_lengths()?;
    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    header += "comment 3D Gaussian splats: f_dc = (rgb - 0.5) / C0, opacity = logit, ";
    header += "scale = ln(std dev), rot = (w, x, y, z)\n";
    header += &format!("element vertex {}\n", set.len());
    let names = [
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
    ];
    let more = [
        "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
    ];
    for name in names.iter().chain(&more).chain(&["confidence"]) {
        header += &format!("property float {name}\n");
    }
    header += "end_header\n";
    w.write_all(header.as_bytes())?;

    const STRIDE: usize = 18 * 4;
    let mut buf = Vec::with_capacity(CHUNK_BYTES + STRIDE);
    for i in 0..set.len() {
        let g = set.get(i);
        let dc = (g.color.as_dvec3() - 0.5) / SH_C0;
        let q = g.rotation;
        let record = [
            g.mean.x,
            g.mean.y,
            g.mean.z,
            0.0,
            0.0,
            0.0,
            dc.x as f32,
            dc.y as f32,
            dc.z as f32,
            opacity_logit(g.opacity) as f32,
            g.log_scale.x,
            g.log_scale.y,
            g.log_scale.z,
            q.w,
            q.x,
            q.y,
            q.z,
            g.confidence,
        ];
        for v in record {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        if buf.len() >= CHUNK_BYTES {
            w.write_all(&buf)?;
            buf.clear();
        }
    }
    w.write_all(&buf)?;
    w.flush()?;
    Ok(())
}

/// Reads a PLY file of 3D Gaussians (see the module documentation for what is accepted).
/// Memory grows with the data actually read, so a header declaring a huge count fails with
/// [`PlyError::Truncated`] at the end of the stream rather than by allocating for it.
pub fn read_ply(r: impl Read) -> Result<GaussianSet, PlyError> {
    let mut r = BufReader::with_capacity(1 << 16, r);
    let header = read_header(&mut r)?;
    read_body(&mut r, &header, None)
}

/// Writes `set` to a file at `path` with [`write_ply`], atomically ([`crate::atomic`]): a
/// crash mid-write leaves the previous file whole, never a header without its records.
pub fn save_ply(set: &GaussianSet, path: impl AsRef<Path>) -> Result<(), PlyError> {
    crate::atomic::write_atomic(path.as_ref(), |w| write_ply(set, w))
}

/// Reads the file at `path` with [`read_ply`]; knowing the file's length, it refuses a
/// header whose counts cannot fit ([`PlyError::TooLarge`]) before reading any record.
pub fn load_ply(path: impl AsRef<Path>) -> Result<GaussianSet, PlyError> {
    let file = File::open(path)?;
    let len = file.metadata()?.len();
    let mut r = CountingReader {
        inner: BufReader::with_capacity(1 << 16, file),
        read: 0,
    };
    let header = read_header(&mut r)?;
    let available = len.saturating_sub(r.read);
    read_body(&mut r.inner, &header, Some(available))
}

/// Counts the bytes consumed through it, to learn the header's length.
struct CountingReader<R> {
    inner: R,
    read: u64,
}

impl<R: Read> Read for CountingReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.read += n as u64;
        Ok(n)
    }
}

impl<R: BufRead> BufRead for CountingReader<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        self.inner.fill_buf()
    }
    fn consume(&mut self, amt: usize) {
        self.read += amt as u64;
        self.inner.consume(amt);
    }
}
