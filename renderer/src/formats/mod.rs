//! The map file formats the splat field exchanges, behind one choice: 3DGS PLY
//! ([`crate::ply`]), Niantic's compressed SPZ ([`spz`]) and binary glTF with
//! `KHR_gaussian_splatting` ([`glb`]). [`save_map`] writes any of them and [`load_map`] reads
//! any of them, telling them apart by their first bytes, not their file names.
//!
//! What every export does first ([`sanitise`]): a Gaussian with a NaN or infinite field is
//! skipped and counted (never written: every format would store it as garbage or not at all),
//! colours and opacities outside [0, 1] are clamped and counted. Each format then states its
//! own precision ([`Exported::max_position_error_m`]).
//!
//! Axes: PLY and SPZ hold the renderer's frame as it is (RDF: x right, y down, z forward,
//! OpenCV's and the 3DGS files'; see [`spz`] for why SPZ does too). glTF has fixed axes (+Y
//! up, cameras looking down -Z: RUB); the frames differ by a half turn about x, so the glTF
//! writer negates y and z ([`to_exchange_frame`], [`rotation_to_exchange`]) and its reader
//! undoes it: a glTF camera with no rotation at the origin sees what the frame's camera sees.

pub mod glb;
pub mod spz;

use std::fmt;
use std::fs::File;
use std::io::{self, Read, Write};
use std::path::Path;
use std::str::FromStr;

use glam::{Quat, Vec3};

use crate::gaussians::{GaussianSet, LengthMismatch};
use crate::ply::{self, PlyError};
use glb::GlbError;
use spz::SpzError;

/// A map file format.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MapFormat {
    /// 3DGS PLY, binary little endian, float properties (the node's default).
    #[default]
    Ply,
    /// Niantic's SPZ: quantised and gzipped, about a tenth of the PLY.
    Spz,
    /// Binary glTF 2.0 with `KHR_gaussian_splatting`.
    Glb,
}

impl MapFormat {
    /// Every format, in the order the docs list them.
    pub const ALL: [MapFormat; 3] = [MapFormat::Ply, MapFormat::Spz, MapFormat::Glb];

    /// The file name extension (without the dot), which is also the format's name on the
    /// command line.
    pub fn extension(self) -> &'static str {
        match self {
            MapFormat::Ply => "ply",
            MapFormat::Spz => "spz",
            MapFormat::Glb => "glb",
        }
    }

    /// The format whose content starts with `head` (at least 4 bytes): `ply` and a newline,
    /// the `glTF` magic, or the gzip magic (SPZ is gzip; [`load_map`] then checks SPZ's own
    /// magic inside). `None` for anything else.
    pub fn sniff(head: &[u8]) -> Option<MapFormat> {
        match head {
            [b'p', b'l', b'y', b'\n' | b'\r', ..] => Some(MapFormat::Ply),
            [b'g', b'l', b'T', b'F', ..] => Some(MapFormat::Glb),
            [0x1f, 0x8b, ..] => Some(MapFormat::Spz),
            _ => None,
        }
    }
}

impl fmt::Display for MapFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.extension())
    }
}

impl FromStr for MapFormat {
    type Err = String;

    /// `ply`, `spz` or `glb` (any case).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        MapFormat::ALL
            .into_iter()
            .find(|f| f.extension().eq_ignore_ascii_case(s))
            .ok_or_else(|| format!("unknown map format `{s}` (ply, spz or glb)"))
    }
}

/// Why a map file could not be written or read; each format's error is kept as the source.
#[derive(Debug, thiserror::Error)]
pub enum MapFileError {
    /// Opening or reading the file failed.
    #[error("map file I/O error")]
    Io(#[from] io::Error),
    /// The content is none of the three formats.
    #[error("not a PLY, SPZ or glTF binary map (the file starts with {0:02x?})")]
    UnknownFormat(Vec<u8>),
    /// The PLY writer or reader failed.
    #[error("PLY")]
    Ply(#[source] PlyError),
    /// The SPZ writer or reader failed.
    #[error("SPZ")]
    Spz(#[source] SpzError),
    /// The glTF writer or reader failed.
    #[error("glTF binary")]
    Glb(#[source] GlbError),
    /// The set to write has arrays of different lengths.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
}

/// What an export wrote.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exported {
    /// The format.
    pub format: MapFormat,
    /// Gaussians written.
    pub gaussians: usize,
    /// Gaussians skipped for a NaN or infinite field (see [`sanitise`]).
    pub skipped_non_finite: usize,
    /// Gaussians whose colour or opacity was clamped to [0, 1].
    pub clamped: usize,
    /// Largest error the format adds to a position, metres: 0 for PLY and glTF (float32 as
    /// the set's), half a fixed-point step for SPZ.
    pub max_position_error_m: f64,
}

/// The set as every format may store it: Gaussians with any NaN or infinite field (or a
/// log-scale whose exponential overflows) left out, colours and opacities clamped to [0, 1].
/// Returns the set and the counts of Gaussians skipped and clamped.
pub fn sanitise(set: &GaussianSet) -> Result<(GaussianSet, usize, usize), LengthMismatch> {
    set.check_lengths()?;
    let mut out = GaussianSet::with_capacity(set.len());
    let (mut skipped, mut clamped) = (0, 0);
    for i in 0..set.len() {
        let mut g = set.get(i);
        let finite = g.mean.is_finite()
            && g.log_scale.exp().is_finite()
            && g.rotation.is_finite()
            && g.opacity.is_finite()
            && g.color.is_finite()
            && g.confidence.is_finite();
        if !finite {
            skipped += 1;
            continue;
        }
        let colour = g.color.clamp(Vec3::ZERO, Vec3::ONE);
        let opacity = g.opacity.clamp(0.0, 1.0);
        if colour != g.color || opacity != g.opacity {
            clamped += 1;
        }
        (g.color, g.opacity) = (colour, opacity);
        out.push(g);
    }
    Ok((out, skipped, clamped))
}

/// Writes `set` in `format` to `w` after [`sanitise`], returning what was written.
pub fn write_map(
    set: &GaussianSet,
    format: MapFormat,
    w: impl Write,
) -> Result<Exported, MapFileError> {
    let (clean, skipped, clamped) = sanitise(set)?;
    let max_position_error_m = match format {
        MapFormat::Ply => ply::write_ply(&clean, w)
            .map(|()| 0.0)
            .map_err(MapFileError::Ply)?,
        MapFormat::Spz => spz::write_spz(&clean, w)
            .map(|s| s.max_position_error_m)
            .map_err(MapFileError::Spz)?,
        MapFormat::Glb => glb::write_glb(&clean, w)
            .map(|()| 0.0)
            .map_err(MapFileError::Glb)?,
    };
    Ok(Exported {
        format,
        gaussians: clean.len(),
        skipped_non_finite: skipped,
        clamped,
        max_position_error_m,
    })
}

/// Writes `set` to `path` with [`write_map`], atomically ([`crate::atomic`]).
pub fn save_map(
    set: &GaussianSet,
    path: impl AsRef<Path>,
    format: MapFormat,
) -> Result<Exported, MapFileError> {
    let mut exported = None;
    crate::atomic::write_atomic(path.as_ref(), |w| {
        exported = Some(write_map(set, format, w)?);
        Ok::<(), MapFileError>(())
    })?;
    // write_atomic calls the closure exactly once before it returns Ok.
    exported.ok_or_else(|| MapFileError::Io(io::Error::other("the map was not written")))
}

/// Reads a map in any of the three formats, chosen by content ([`MapFormat::sniff`]).
pub fn read_map(mut r: impl Read) -> Result<(MapFormat, GaussianSet), MapFileError> {
    let mut head = Vec::with_capacity(4);
    (&mut r).take(4).read_to_end(&mut head)?;
    let format =
        MapFormat::sniff(&head).ok_or_else(|| MapFileError::UnknownFormat(head.clone()))?;
    let r = head.as_slice().chain(r);
    let set = match format {
        MapFormat::Ply => ply::read_ply(r).map_err(MapFileError::Ply)?,
        MapFormat::Spz => spz::read_spz(r).map_err(MapFileError::Spz)?,
        MapFormat::Glb => glb::read_glb(r).map_err(MapFileError::Glb)?,
    };
    Ok((format, set))
}

/// Reads the map file at `path` in any of the three formats, chosen by content; PLY goes
/// through [`ply::load_ply`], which refuses impossible counts before reading.
pub fn load_map(path: impl AsRef<Path>) -> Result<(MapFormat, GaussianSet), MapFileError> {
    let path = path.as_ref();
    let mut head = Vec::with_capacity(4);
    File::open(path)?.take(4).read_to_end(&mut head)?;
    match MapFormat::sniff(&head) {
        Some(MapFormat::Ply) => Ok((
            MapFormat::Ply,
            ply::load_ply(path).map_err(MapFileError::Ply)?,
        )),
        Some(_) => read_map(io::BufReader::new(File::open(path)?)),
        None => Err(MapFileError::UnknownFormat(head)),
    }
}

/// A point of the renderer's RDF frame in glTF's RUB axes (y and z negated).
pub fn to_exchange_frame(p: Vec3) -> Vec3 {
    Vec3::new(p.x, -p.y, -p.z)
}

/// The inverse of [`to_exchange_frame`] (the same map).
pub fn from_exchange_frame(p: Vec3) -> Vec3 {
    to_exchange_frame(p)
}

/// A rotation of the renderer's RDF frame in glTF's RUB axes: the frames differ by a half
/// turn about x, so conjugating by it negates the quaternion's y and z (as the reference SPZ
/// code's `flipQ` does when it converts).
pub fn rotation_to_exchange(q: Quat) -> Quat {
    Quat::from_xyzw(q.x, -q.y, -q.z, q.w)
}

/// The inverse of [`rotation_to_exchange`] (the same map).
pub fn rotation_from_exchange(q: Quat) -> Quat {
    rotation_to_exchange(q)
}

/// `q` normalised; a zero or non-finite quaternion is the identity, as the rasterizers take
/// it.
pub fn unit_rotation(q: Quat) -> Quat {
    let len = q.length();
    if len.is_finite() && len > 0.0 {
        q / len
    } else {
        Quat::IDENTITY
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod frame_tests {
    use super::*;

    #[test]
    fn the_gltf_frame_flips_y_and_z_and_is_its_own_inverse() {
        let p = Vec3::new(1.0, 2.0, 3.0);
        assert_eq!(to_exchange_frame(p), Vec3::new(1.0, -2.0, -3.0));
        assert_eq!(from_exchange_frame(to_exchange_frame(p)), p);
        // Rotating then changing axes equals changing axes then applying the converted
        // rotation.
        let q = Quat::from_axis_angle(Vec3::new(0.3, 1.0, -0.4).normalize(), 0.9);
        let e = rotation_to_exchange(q);
        let v = Vec3::new(0.2, 0.7, -0.1);
        assert!(to_exchange_frame(q * v).abs_diff_eq(e * to_exchange_frame(v), 1e-6));
        assert_eq!(rotation_from_exchange(e), q);
    }
}
