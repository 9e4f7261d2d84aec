//! Gaussian maps as `sensor_msgs/PointCloud2`, one point per Gaussian, with the channels and
//! value conventions of the 3DGS PLY files ([`renderer::ply`]) so splat tools read them:
//!
//! `x y z` position; `f_dc_0..2` = `(colour - 0.5) / SH_C0`; `opacity` = logit of the opacity
//! clamped to `[OPACITY_EPS, 1 - OPACITY_EPS]`; `scale_0..2` = log standard deviations;
//! `rot_0..3` = quaternion `(w, x, y, z)`; `confidence`. All FLOAT32, except positions in
//! world-frame clouds.
//!
//! Then `rgb`, the packed colour of the PCL / ROS convention that RViz2's and Foxglove's
//! point-cloud displays colour by: a FLOAT32 channel whose 32 bits are the integer
//! `0x00RRGGBB`, each channel the SH DC colour `0.5 + SH_C0 * f_dc` clamped to [0, 1] and
//! rounded to 8 bits (NaN as 0). Read it as a `uint32` (`struct.unpack('<I',
//! struct.pack('<f', rgb))` in Python, `reinterpret_cast` in C++); as a float it is a tiny
//! number (below 1e-37) and means nothing. It is derived from `f_dc_0..2`, so the reader below
//! does not need it and clouds without it (written before it existed) decode the same.
//!
//! Positions: a bin map lives in its bin frame (the header's `frame_id` names it) and its
//! positions are FLOAT32 as they are. The global map lives in the world frame, where f32
//! loses centimetres 100 km out; its positions are written as FLOAT64 `x y z` (an `origin`
//! given in f64 plus the set's f32 offsets from it), so any PointCloud2 reader gets exact
//! world coordinates without a side channel. Records are 64 bytes (f32 positions, `rgb` at
//! offset 60) or 76 bytes (f64 positions, then the 12 f32 channels at offset 24 and `rgb` at
//! offset 72); `height = 1`, little endian, `is_dense = true`.
//!
//! The reader takes any record layout: the named channels anywhere in the record, FLOAT32 or
//! FLOAT64, either byte order, `confidence` optional (1 when absent), extra channels ignored.
//! Rotations are read as stored, not normalised, as the PLY reader does.

use glam::{DVec3, Quat, Vec3};
use renderer::picture::unit_to_u8;
use renderer::ply::{opacity_from_logit, opacity_logit, SH_C0};
use renderer::GaussianSet;

use super::sensor_msgs::{datatype, PointCloud2, PointField};
use super::std_msgs::Header;
use super::ConvertError;

/// The channels in record order.
pub const FIELD_NAMES: [&str; 15] = [
    "x",
    "y",
    "z",
    "f_dc_0",
    "f_dc_1",
    "f_dc_2",
    "opacity",
    "scale_0",
    "scale_1",
    "scale_2",
    "rot_0",
    "rot_1",
    "rot_2",
    "rot_3",
    "confidence",
];

/// The packed-colour channel written after [`FIELD_NAMES`] (see the module documentation).
pub const RGB_FIELD: &str = "rgb";

/// The PCL / ROS packed colour of an SH DC coefficient triple: `0x00RRGGBB` with each channel
/// `0.5 + SH_C0 * f_dc` clamped to [0, 1] and rounded to 8 bits (NaN as 0), as the FLOAT32 whose
/// bits those are.
pub fn packed_rgb(f_dc: [f64; 3]) -> f32 {
    let [r, g, b] = f_dc.map(|dc| u32::from(unit_to_u8((0.5 + SH_C0 * dc) as f32)));
    f32::from_bits((r << 16) | (g << 8) | b)
}

/// One Gaussian's stored values, in [`FIELD_NAMES`] order and the PLY conventions.
pub type Record = [f64; 15];

/// The record of `g` placed at `position` (its own `mean` is not used), so world-frame maps
/// with f64 positions and bin maps share one layout.
pub fn record(position: DVec3, g: &renderer::Gaussian) -> Record {
    let dc = (g.color.as_dvec3() - 0.5) / SH_C0;
    let s = g.log_scale.as_dvec3();
    let q = g.rotation.as_dquat();
    [
        position.x,
        position.y,
        position.z,
        dc.x,
        dc.y,
        dc.z,
        opacity_logit(g.opacity),
        s.x,
        s.y,
        s.z,
        q.w,
        q.x,
        q.y,
        q.z,
        g.confidence as f64,
    ]
}

/// The Gaussian a record holds; its mean is the stored position minus `origin`, formed in
/// f64 and then cast to f32.
pub fn gaussian(r: &Record, origin: DVec3) -> renderer::Gaussian {
    let dc = DVec3::new(r[3], r[4], r[5]);
    renderer::Gaussian {
        mean: (DVec3::new(r[0], r[1], r[2]) - origin).as_vec3(),
        color: (0.5 + SH_C0 * dc).as_vec3(),
        opacity: opacity_from_logit(r[6]),
        log_scale: Vec3::new(r[7] as f32, r[8] as f32, r[9] as f32),
        rotation: Quat::from_xyzw(r[11] as f32, r[12] as f32, r[13] as f32, r[10] as f32),
        confidence: r[14] as f32,
    }
}

/// The cloud of `set`. With `origin` `None` positions are the set's own, FLOAT32 (a bin map
/// in its bin frame); with `Some(origin)` they are `origin + mean` computed and written in
/// FLOAT64 (a world-frame map whose means are offsets from `origin`).
pub fn cloud_from_gaussians(
    set: &GaussianSet,
    header: Header,
    origin: Option<DVec3>,
) -> Result<PointCloud2, ConvertError> {
    set.check_lengths()?;
    let o = origin.unwrap_or(DVec3::ZERO);
    let records = (0..set.len()).map(|i| {
        let g = set.get(i);
        record(o + g.mean.as_dvec3(), &g)
    });
    cloud_from_records(records, header, origin.is_some())
}

/// The cloud of `records`, positions FLOAT64 when `f64_positions`, else FLOAT32. The
/// records are taken one by one into the cloud's data, never held together beside it.
pub fn cloud_from_records(
    records: impl ExactSizeIterator<Item = Record>,
    header: Header,
    f64_positions: bool,
) -> Result<PointCloud2, ConvertError> {
    let mut cloud = cloud_layout(records.len(), header, f64_positions)?;
    cloud.data.reserve_exact(cloud.row_step as usize);
    for v in records {
        put_record(&mut cloud.data, &v, f64_positions);
    }
    Ok(cloud)
}

/// The cloud of `points` records (positions FLOAT64 when `f64_positions`) without its data:
/// the fields, sizes and steps, for a writer that appends the records itself
/// ([`put_record`], [`PointCloud2::write_with_data`]).
pub fn cloud_layout(
    points: usize,
    header: Header,
    f64_positions: bool,
) -> Result<PointCloud2, ConvertError> {
    let (pos_type, pos_size) = match f64_positions {
        true => (datatype::FLOAT64, 8),
        false => (datatype::FLOAT32, 4),
    };
    let fields: Vec<PointField> = FIELD_NAMES
        .iter()
        .chain(&[RGB_FIELD])
        .enumerate()
        .map(|(i, name)| PointField {
            name: (*name).to_owned(),
            offset: if i < 3 {
                i as u32 * pos_size
            } else {
                3 * pos_size + 4 * (i as u32 - 3)
            },
            datatype: if i < 3 { pos_type } else { datatype::FLOAT32 },
            count: 1,
        })
        .collect();
    let point_step = 3 * pos_size + 4 * 13;
    let too_large = || ConvertError::TooLarge("the Gaussian cloud");
    let width = u32::try_from(points).map_err(|_| too_large())?;
    let row_step = width.checked_mul(point_step).ok_or_else(too_large)?;
    Ok(PointCloud2 {
        header,
        height: 1,
        width,
        fields,
        is_bigendian: false,
        point_step,
        row_step,
        data: Vec::new(),
        is_dense: true,
    })
}

/// Appends one record to a cloud's data in the layout of [`cloud_layout`].
pub fn put_record(data: &mut Vec<u8>, v: &Record, f64_positions: bool) {
    for (j, x) in v.iter().enumerate() {
        if j < 3 && f64_positions {
            data.extend_from_slice(&x.to_le_bytes());
        } else {
            data.extend_from_slice(&(*x as f32).to_le_bytes());
        }
    }
    data.extend_from_slice(&packed_rgb([v[3], v[4], v[5]]).to_le_bytes());
}

/// Where one channel sits in a record and how it is stored.
#[derive(Clone, Copy, Debug)]
struct Channel {
    offset: usize,
    f64: bool,
}

/// Finds channel `name` and checks it is one float inside the record.
fn channel(cloud: &PointCloud2, name: &'static str) -> Result<Option<Channel>, ConvertError> {
    let Some(f) = cloud.fields.iter().find(|f| f.name == name) else {
        return Ok(None);
    };
    let bad = |reason: String| ConvertError::BadField {
        name: name.to_owned(),
        reason,
    };
    let size = match f.datatype {
        datatype::FLOAT32 => 4,
        datatype::FLOAT64 => 8,
        other => {
            return Err(bad(format!(
                "datatype {other}, not FLOAT32 (7) or FLOAT64 (8)"
            )))
        }
    };
    if f.count != 1 {
        return Err(bad(format!("count {}, not 1", f.count)));
    }
    if f.offset as u64 + size > cloud.point_step as u64 {
        return Err(bad(format!(
            "offset {} + {size} bytes past point_step {}",
            f.offset, cloud.point_step
        )));
    }
    Ok(Some(Channel {
        offset: f.offset as usize,
        f64: size == 8,
    }))
}

/// Reads one channel of a record.
fn value(record: &[u8], c: Channel, big_endian: bool) -> f64 {
    let at = c.offset;
    if c.f64 {
        let mut b = [0; 8];
        b.copy_from_slice(&record[at..at + 8]);
        if big_endian {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    } else {
        let mut b = [0; 4];
        b.copy_from_slice(&record[at..at + 4]);
        if big_endian {
            f32::from_be_bytes(b) as f64
        } else {
            f32::from_le_bytes(b) as f64
        }
    }
}

/// The Gaussians of a cloud, positions made relative to `origin` (in f64, then cast to f32):
/// `DVec3::ZERO` for a bin-frame cloud, the map origin for a world-frame one. See
/// [`records_from_cloud`] for what is read.
pub fn gaussians_from_cloud(
    cloud: &PointCloud2,
    origin: DVec3,
) -> Result<GaussianSet, ConvertError> {
    let records = records_from_cloud(cloud)?;
    let mut set = GaussianSet::with_capacity(records.len());
    for r in &records {
        set.push(gaussian(r, origin));
    }
    Ok(set)
}

/// The records of a cloud, in point order. See the module documentation for the layouts
/// read; a missing channel (other than `confidence`, 1 when absent), a channel that is not
/// one float inside the record, or sizes that disagree with the data are errors.
pub fn records_from_cloud(cloud: &PointCloud2) -> Result<Vec<Record>, ConvertError> {
    let mut channels = [None; 15];
    for (slot, name) in channels.iter_mut().zip(FIELD_NAMES) {
        *slot = match channel(cloud, name)? {
            Some(c) => Some(c),
            None if name == "confidence" => None,
            None => return Err(ConvertError::MissingField(name)),
        };
    }
    let (w, h) = (cloud.width as u64, cloud.height as u64);
    let (point_step, row_step) = (cloud.point_step as u64, cloud.row_step as u64);
    if row_step < w * point_step || cloud.data.len() as u64 != row_step * h {
        return Err(ConvertError::CloudSize {
            width: cloud.width,
            height: cloud.height,
            point_step: cloud.point_step,
            row_step: cloud.row_step,
            len: cloud.data.len(),
        });
    }
    // Each point holds at least one 4-byte channel inside the data checked above, so this
    // count is bounded by the message's length.
    let mut records = Vec::with_capacity((w * h) as usize);
    let rows = cloud.data.chunks_exact(cloud.row_step.max(1) as usize);
    for row in rows.take(cloud.height as usize) {
        for bytes in row
            .chunks_exact(point_step as usize)
            .take(cloud.width as usize)
        {
            records.push(std::array::from_fn(|i| {
                channels[i].map_or(1.0, |c| value(bytes, c, cloud.is_bigendian))
            }));
        }
    }
    Ok(records)
}
