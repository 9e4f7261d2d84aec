//! Gaussian sets as SPZ, Niantic's compressed splat format (`nianticlabs/spz`, `load-spz.cc`
//! and its README), which three.js, Spark, PlayCanvas, SuperSplat and splat-transform read.
//!
//! A gzip stream of a 16-byte little-endian header (`magic` 0x5053474e "NGSP", `version`,
//! `numPoints`, `shDegree`, `fractionalBits`, `flags`, a reserved byte) and then the
//! attributes, each for all points in turn: positions (three 24-bit two's-complement fixed-point
//! numbers with `fractionalBits` fractional bits), alphas (8 bits, opacity * 255), colours (8
//! bits per channel, the SH DC coefficient as `f_dc * 0.15 * 255 + 127.5`), scales (8 bits per
//! axis, `(ln sigma + 10) * 16`), rotations (version 3: the smallest three components of the
//! unit quaternion in 10 bits each plus the largest one's index in 2; version 2: `x y z` of the
//! quaternion with `w >= 0` in 8 bits each) and spherical-harmonic coefficients above degree 0.
//!
//! Axes: the reference library converts to RUB (x right, y up, z back) only when a caller
//! names the source's coordinate system; its own `ply_to_spz` tool names none, and the readers
//! tested here (splat-transform, Spark) read SPZ as they read 3DGS PLY. So SPZ files in the
//! field hold the PLY files' axes as they are, and so does this writer: positions and
//! rotations in the renderer's frame (RDF: x right, y down, z forward, as the PLY files), and
//! an SPZ opens exactly like the PLY of the same map. The writer writes version 3 with SH
//! degree 0 (the renderer's colours are degree 0), no flags; `confidence` has no place in SPZ
//! and reads back as 1.
//!
//! Positions: the reference always writes 12 fractional bits (0.24 mm steps), which holds
//! coordinates up to 2048 m. Maps here can be larger, so the writer takes the most fractional
//! bits, up to 12, that hold the set's largest coordinate ([`fractional_bits_for`]): a map
//! within 2 km keeps 0.24 mm, one reaching 100 km keeps 1/64 m (error at most 7.8 mm), and a
//! set beyond 8,388 km is refused ([`SpzError::TooFar`]) rather than written wrong. Readers
//! honour the header's `fractionalBits`, so no offset needs to travel beside the file.
//!
//! The reader takes versions 2 and 3, any SH degree up to 4 (higher coefficients skipped),
//! and refuses what it does not know (another magic or version, extensions) with a typed
//! error. It never panics and grows memory only with data actually decompressed.

use std::io::{self, Read, Write};

use flate2::read::GzDecoder;
use flate2::write::GzEncoder;
use flate2::Compression;
use glam::{Quat, Vec3};

use super::unit_rotation;
use crate::gaussians::{Gaussian, GaussianSet, LengthMismatch};
use crate::ply::SH_C0;

/// The header's magic number, "NGSP" read as a little-endian `u32`.
pub const MAGIC: u32 = 0x5053_474e;
/// The version the writer writes (smallest-three rotations).
pub const VERSION: u32 = 3;
/// The reference's scale of the colour bytes: `byte = f_dc * COLOR_SCALE * 255 + 127.5`.
pub const COLOR_SCALE: f64 = 0.15;
/// The most fractional bits the writer uses, as the reference does (0.24 mm steps).
pub const MAX_FRACTIONAL_BITS: u8 = 12;
/// The most points the reader accepts, the reference reader's limit.
pub const MAX_POINTS: u32 = 10_000_000;
/// Largest magnitude of a 24-bit two's-complement number.
const MAX_FIXED: f64 = ((1 << 23) - 1) as f64;
/// Header flag: the stream carries extension records (not read here).
const FLAG_EXTENSIONS: u8 = 0x2;
/// Header size, bytes.
const HEADER_BYTES: usize = 16;

/// Everything that can go wrong writing or reading SPZ.
#[derive(Debug, thiserror::Error)]
pub enum SpzError {
    /// The underlying reader, writer or gzip stream failed.
    #[error("SPZ I/O error")]
    Io(#[from] io::Error),
    /// The decompressed stream does not start with the SPZ magic.
    #[error("not an SPZ file (magic {found:#010x}, 0x5053474e expected)")]
    NotSpz {
        /// The first four bytes, little endian.
        found: u32,
    },
    /// A version this reader does not read (2 and 3 are).
    #[error("SPZ version {0} is not supported (2 and 3 are)")]
    UnsupportedVersion(u32),
    /// A header value out of range, or a feature not read here.
    #[error("bad SPZ header: {0}")]
    BadHeader(String),
    /// The header declares more points than the reader accepts.
    #[error("SPZ header declares {0} points, more than the {MAX_POINTS} accepted")]
    TooLarge(u32),
    /// The stream ends before the data its header declares.
    #[error("SPZ data truncated: {expected} bytes declared after the header, {got} present")]
    Truncated {
        /// Bytes the header declares.
        expected: u64,
        /// Bytes present.
        got: u64,
    },
    /// A value the format cannot hold; the writer refuses rather than write it wrong.
    #[error("Gaussian {index}: {what} is not finite; SPZ cannot hold it")]
    NonFinite {
        /// The Gaussian's index in the set.
        index: usize,
        /// The field.
        what: &'static str,
    },
    /// A coordinate beyond what 24-bit fixed point holds with any fractional bits.
    #[error("a coordinate of {max_abs_m} m is beyond SPZ's range of 8,388,607 m (24-bit fixed point); export in a frame nearer the map")]
    TooFar {
        /// The largest coordinate magnitude in the set, metres.
        max_abs_m: f64,
    },
    /// The set to write has arrays of different lengths.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
}

/// What the writer chose, for callers that report it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpzWritten {
    /// Fractional bits of the positions.
    pub fractional_bits: u8,
    /// Largest position error the fixed point can add, metres (half a step).
    pub max_position_error_m: f64,
}

/// The most fractional bits, at most [`MAX_FRACTIONAL_BITS`], with which 24-bit fixed point
/// holds coordinates up to `max_abs` metres; `None` when none does.
pub fn fractional_bits_for(max_abs: f64) -> Option<u8> {
    (0..=MAX_FRACTIONAL_BITS)
        .rev()
        .find(|&b| (max_abs * f64::from(1u32 << b)).round() <= MAX_FIXED)
}

/// Writes `set` as SPZ version 3 (see the module documentation). Colours are clamped to
/// [0, 1], opacities to [0, 1]; a non-finite value is refused ([`SpzError::NonFinite`]), as
/// is a coordinate beyond the format's range ([`SpzError::TooFar`]).
pub fn write_spz(set: &GaussianSet, w: impl Write) -> Result<SpzWritten, SpzError> {
    set.check_lengths()?;
    let n = set.len();
    let mut max_abs = 0.0f64;
    for i in 0..n {
        let g = set.get(i);
        let checks = [
            ("position", g.mean.is_finite()),
            ("scale", g.log_scale.is_finite()),
            ("rotation", g.rotation.is_finite()),
            ("opacity", g.opacity.is_finite()),
            ("colour", g.color.is_finite()),
        ];
        if let Some((what, _)) = checks.iter().find(|(_, ok)| !ok) {
            return Err(SpzError::NonFinite { index: i, what });
        }
        max_abs = max_abs.max(f64::from(g.mean.abs().max_element()));
    }
    let bits = fractional_bits_for(max_abs).ok_or(SpzError::TooFar { max_abs_m: max_abs })?;
    let count = u32::try_from(n)
        .ok()
        .filter(|&c| c <= MAX_POINTS)
        .ok_or_else(|| SpzError::BadHeader(format!("{n} points, at most {MAX_POINTS}")))?;

    let mut data = Vec::with_capacity(HEADER_BYTES + n * 20);
    data.extend_from_slice(&MAGIC.to_le_bytes());
    data.extend_from_slice(&VERSION.to_le_bytes());
    data.extend_from_slice(&count.to_le_bytes());
    data.extend_from_slice(&[0, bits, 0, 0]);
    let step = f64::from(1u32 << bits);
    for m in &set.means {
        for v in m.to_array() {
            let fixed = (f64::from(v) * step).round() as i32;
            data.extend_from_slice(&fixed.to_le_bytes()[..3]);
        }
    }
    data.extend(set.opacities.iter().map(|&a| unit_byte(f64::from(a))));
    for c in &set.colors {
        for v in c.to_array() {
            let f_dc = (f64::from(v).clamp(0.0, 1.0) - 0.5) / SH_C0;
            data.push(byte(f_dc * COLOR_SCALE * 255.0 + 127.5));
        }
    }
    for s in &set.log_scales {
        data.extend(s.to_array().map(|v| byte((f64::from(v) + 10.0) * 16.0)));
    }
    for q in &set.rotations {
        data.extend_from_slice(&pack_smallest_three(unit_rotation(*q)).to_le_bytes());
    }
    let mut gz = GzEncoder::new(w, Compression::default());
    gz.write_all(&data)?;
    gz.finish()?.flush()?;
    Ok(SpzWritten {
        fractional_bits: bits,
        max_position_error_m: 0.5 / step,
    })
}

/// Reads an SPZ stream (gzip) of version 2 or 3 (see the module documentation).
pub fn read_spz(r: impl Read) -> Result<GaussianSet, SpzError> {
    let mut gz = GzDecoder::new(r);
    let mut header = [0u8; HEADER_BYTES];
    let got = read_up_to(&mut gz, &mut header)?;
    let word =
        |i: usize| u32::from_le_bytes([header[i], header[i + 1], header[i + 2], header[i + 3]]);
    if got >= 4 && word(0) != MAGIC {
        return Err(SpzError::NotSpz { found: word(0) });
    }
    if got < HEADER_BYTES {
        return Err(SpzError::Truncated {
            expected: HEADER_BYTES as u64,
            got: got as u64,
        });
    }
    let (version, count) = (word(4), word(8));
    let (sh_degree, bits, flags) = (header[12], header[13], header[14]);
    if !(2..=3).contains(&version) {
        return Err(SpzError::UnsupportedVersion(version));
    }
    if count > MAX_POINTS {
        return Err(SpzError::TooLarge(count));
    }
    let sh_dim: u64 = match sh_degree {
        0 => 0,
        1 => 3,
        2 => 8,
        3 => 15,
        4 => 24,
        d => return Err(SpzError::BadHeader(format!("SH degree {d}, at most 4"))),
    };
    if bits > 23 {
        return Err(SpzError::BadHeader(format!("{bits} fractional bits of 24")));
    }
    if flags & FLAG_EXTENSIONS != 0 {
        return Err(SpzError::BadHeader(
            "extension records are not read here".into(),
        ));
    }
    let rotation_bytes: u64 = if version >= 3 { 4 } else { 3 };
    let n = u64::from(count);
    let expected = n * (9 + 1 + 3 + 3 + rotation_bytes + 3 * sh_dim);
    let mut data = Vec::new();
    gz.take(expected).read_to_end(&mut data)?;
    if (data.len() as u64) < expected {
        return Err(SpzError::Truncated {
            expected,
            got: data.len() as u64,
        });
    }
    let n = n as usize;
    let (positions, rest) = data.split_at(9 * n);
    let (alphas, rest) = rest.split_at(n);
    let (colours, rest) = rest.split_at(3 * n);
    let (scales, rotations) = rest.split_at(3 * n);
    let step = 1.0 / f64::from(1u32 << bits);
    let mut set = GaussianSet::with_capacity(n);
    for i in 0..n {
        let p = &positions[9 * i..9 * i + 9];
        let fixed = |k: usize| {
            let v = i32::from_le_bytes([p[3 * k], p[3 * k + 1], p[3 * k + 2], 0]);
            ((v << 8) >> 8) as f64 * step
        };
        let mean = Vec3::new(fixed(0) as f32, fixed(1) as f32, fixed(2) as f32);
        let c = &colours[3 * i..3 * i + 3];
        let colour = |k: usize| {
            let f_dc = (f64::from(c[k]) / 255.0 - 0.5) / COLOR_SCALE;
            (0.5 + SH_C0 * f_dc) as f32
        };
        let s = &scales[3 * i..3 * i + 3];
        let log_scale = |k: usize| f32::from(s[k]) / 16.0 - 10.0;
        let rotation = if version >= 3 {
            let r = &rotations[4 * i..4 * i + 4];
            unpack_smallest_three(u32::from_le_bytes([r[0], r[1], r[2], r[3]]))
        } else {
            let r = &rotations[3 * i..3 * i + 3];
            unpack_first_three([r[0], r[1], r[2]])
        };
        set.push(Gaussian {
            mean,
            log_scale: Vec3::new(log_scale(0), log_scale(1), log_scale(2)),
            rotation,
            opacity: f32::from(alphas[i]) / 255.0,
            color: Vec3::new(colour(0), colour(1), colour(2)),
            confidence: 1.0,
        });
    }
    Ok(set)
}

/// Reads into `buf` until it is full or the stream ends; returns the bytes read.
fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// `x` rounded and clamped to a byte.
fn byte(x: f64) -> u8 {
    x.round().clamp(0.0, 255.0) as u8
}

/// A value in [0, 1] (clamped) as a byte.
fn unit_byte(x: f64) -> u8 {
    byte(x.clamp(0.0, 1.0) * 255.0)
}

/// Version 3 rotation: the index of the largest-magnitude component (x, y, z, w order) in the
/// top 2 bits, then each other component, in order, as a sign bit and 9 bits of
/// `|v| / sqrt(1/2)`, the sign relative to the largest component's (so it need not be stored).
fn pack_smallest_three(q: Quat) -> u32 {
    let v = q.to_array();
    let largest = (0..4)
        .max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs()))
        .unwrap_or(3);
    let negate = v[largest] < 0.0;
    let mut comp = largest as u32;
    for (i, x) in v.iter().enumerate() {
        if i != largest {
            let negbit = u32::from((*x < 0.0) != negate);
            let mag = (511.0 * (x.abs() / std::f32::consts::FRAC_1_SQRT_2) + 0.5).min(511.0) as u32;
            comp = (comp << 10) | (negbit << 9) | mag;
        }
    }
    comp
}

/// The inverse of [`pack_smallest_three`]; the largest component is `sqrt(1 - sum of the
/// others' squares)`, clamped at 0 so a damaged word still gives a finite quaternion.
fn unpack_smallest_three(mut comp: u32) -> Quat {
    let largest = (comp >> 30) as usize;
    let mut v = [0.0f32; 4];
    let mut sum = 0.0;
    for i in (0..4).rev() {
        if i != largest {
            let mag = (comp & 511) as f32;
            let neg = (comp >> 9) & 1 == 1;
            comp >>= 10;
            let x = std::f32::consts::FRAC_1_SQRT_2 * mag / 511.0;
            v[i] = if neg { -x } else { x };
            sum += x * x;
        }
    }
    v[largest] = (1.0 - sum).max(0.0).sqrt();
    Quat::from_array(v)
}

/// Version 2 rotation: `x y z` of the quaternion with `w >= 0`, each `v * 127.5 + 127.5`;
/// `w = sqrt(1 - |xyz|^2)`, clamped at 0.
fn unpack_first_three(r: [u8; 3]) -> Quat {
    let xyz = Vec3::new(r[0] as f32, r[1] as f32, r[2] as f32) / 127.5 - Vec3::ONE;
    let w = (1.0 - xyz.length_squared()).max(0.0).sqrt();
    Quat::from_xyzw(xyz.x, xyz.y, xyz.z, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rotations() -> Vec<Quat> {
        vec![
            Quat::IDENTITY,
            Quat::from_xyzw(0.0, 0.0, 0.0, -1.0),
            Quat::from_rotation_y(2.5),
            Quat::from_axis_angle(Vec3::new(0.3, -0.8, 0.5).normalize(), -1.9),
            Quat::from_xyzw(0.5, -0.5, 0.5, -0.5),
        ]
    }

    /// The same rotation: q and -q agree.
    fn same_rotation(a: Quat, b: Quat) -> f32 {
        1.0 - a.dot(b).abs()
    }

    #[test]
    fn smallest_three_keeps_rotations_within_its_10_bit_steps() {
        for q in rotations() {
            let back = unpack_smallest_three(pack_smallest_three(q));
            assert!((back.length() - 1.0).abs() < 1e-6, "{q} -> {back}");
            // 9 magnitude bits over [0, sqrt(1/2)]: each component within 7e-4.
            assert!(same_rotation(q, back) < 5e-6, "{q} -> {back}");
        }
    }

    #[test]
    fn fractional_bits_shrink_with_the_extent_and_stop_at_24_bits() {
        assert_eq!(fractional_bits_for(0.0), Some(12));
        assert_eq!(fractional_bits_for(2047.0), Some(12));
        assert_eq!(fractional_bits_for(2048.0), Some(11));
        assert_eq!(fractional_bits_for(1e5), Some(6));
        assert_eq!(fractional_bits_for(8_388_607.0), Some(0));
        assert_eq!(fractional_bits_for(8_388_608.0), None);
    }

    #[test]
    fn wrong_magic_version_and_truncation_are_typed_errors() {
        let gz = |bytes: &[u8]| {
            let mut e = GzEncoder::new(Vec::new(), Compression::fast());
            e.write_all(bytes).unwrap();
            e.finish().unwrap()
        };
        let mut header = Vec::new();
        header.extend_from_slice(&MAGIC.to_le_bytes());
        header.extend_from_slice(&3u32.to_le_bytes());
        header.extend_from_slice(&2u32.to_le_bytes());
        header.extend_from_slice(&[0, 12, 0, 0]);
        let err = read_spz(gz(&header).as_slice()).unwrap_err();
        assert!(
            matches!(
                err,
                SpzError::Truncated {
                    expected: 40,
                    got: 0
                }
            ),
            "{err}"
        );
        let mut v4 = header.clone();
        v4[4] = 4;
        assert!(matches!(
            read_spz(gz(&v4).as_slice()),
            Err(SpzError::UnsupportedVersion(4))
        ));
        assert!(matches!(
            read_spz(gz(b"ply\nformat").as_slice()),
            Err(SpzError::NotSpz { .. })
        ));
        assert!(matches!(read_spz(&b"not gzip"[..]), Err(SpzError::Io(_))));
        let mut huge = header.clone();
        huge[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(
            read_spz(gz(&huge).as_slice()),
            Err(SpzError::TooLarge(u32::MAX))
        ));
    }
}
