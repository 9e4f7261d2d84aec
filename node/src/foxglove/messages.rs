//! The node's outputs as Foxglove's own schemas, built with the SDK's message types:
//! Gaussian maps as `foxglove.PointCloud` (position and colour), images as
//! `foxglove.RawImage` (`rgb8`), frames as `foxglove.FrameTransform`; and the JSON (with its
//! JSON Schema) of the per-bin latency and the counters, which have no Foxglove schema.
//!
//! A point is [`POINT_STRIDE`] bytes: `x y z` as little-endian f32, then `red green blue
//! alpha` as u8. The colour is the map's SH degree-0 colour, `0.5 + SH_C0 * f_dc` (what the
//! map's `f_dc_0..2` fields and its PLY encode), clamped to [0, 1] and rounded to 8 bits; the
//! alpha is the opacity the same way. Foxglove's 3D panel colours such a cloud by its
//! `red green blue alpha` fields ("RGBA (separate fields)").

use ::foxglove::bytes::Bytes;
use ::foxglove::messages::packed_element_field::NumericType;
use ::foxglove::messages::{
    FrameTransform, PackedElementField, PointCloud, Pose, Quaternion, RawImage, Timestamp, Vector3,
};
use glam::{DAffine3, DQuat, DVec3, Vec3};
use model::frame::RgbImage;
use renderer::picture::unit_to_u8;
use renderer::GaussianSet;
use serde_json::{json, Value};

use crate::counters::Counters;
use crate::fusion::WorldGaussian;
use crate::msg::latency::BinLatency;

/// Bytes per point: `x y z` (f32), then `red green blue alpha` (u8).
pub const POINT_STRIDE: u32 = 16;

/// A stamp in ns since the Unix epoch as Foxglove's timestamp: negative stamps become 0 and
/// stamps past 2106 (u32 seconds) the last representable second.
pub fn timestamp(ns: i64) -> Timestamp {
    let ns = ns.max(0) as u64;
    let sec = u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new(sec, (ns % 1_000_000_000) as u32)
}

/// A colour and opacity as the cloud's 8-bit `red green blue alpha`: each clamped to
/// [0, 1] and rounded (NaN gives 0).
pub fn rgba8(color: Vec3, opacity: f32) -> [u8; 4] {
    [
        unit_to_u8(color.x),
        unit_to_u8(color.y),
        unit_to_u8(color.z),
        unit_to_u8(opacity),
    ]
}

/// The `fields` of every cloud the node sends (see [`POINT_STRIDE`]).
fn fields() -> Vec<PackedElementField> {
    let field = |name: &str, offset: u32, t: NumericType| PackedElementField {
        name: name.into(),
        offset,
        r#type: t as i32,
    };
    vec![
        field("x", 0, NumericType::Float32),
        field("y", 4, NumericType::Float32),
        field("z", 8, NumericType::Float32),
        field("red", 12, NumericType::Uint8),
        field("green", 13, NumericType::Uint8),
        field("blue", 14, NumericType::Uint8),
        field("alpha", 15, NumericType::Uint8),
    ]
}

/// A pose of `to_parent` (child to parent) as Foxglove's position and orientation.
fn pose_parts(to_parent: &DAffine3) -> (Vector3, Quaternion) {
    let q = DQuat::from_mat3(&to_parent.matrix3).normalize();
    let p = to_parent.translation;
    (
        Vector3 {
            x: p.x,
            y: p.y,
            z: p.z,
        },
        Quaternion {
            x: q.x,
            y: q.y,
            z: q.z,
            w: q.w,
        },
    )
}

/// A cloud in `frame_id` whose points are given relative to `origin` (a translation in that
/// frame, carried in the cloud's f64 pose, so points far from the frame's origin keep f32's
/// precision near `origin`).
fn cloud(
    frame_id: String,
    stamp_ns: i64,
    origin: DVec3,
    points: impl ExactSizeIterator<Item = (Vec3, [u8; 4])>,
) -> PointCloud {
    let mut data = Vec::with_capacity(points.len() * POINT_STRIDE as usize);
    for (p, rgba) in points {
        for v in [p.x, p.y, p.z] {
            data.extend_from_slice(&v.to_le_bytes());
        }
        data.extend_from_slice(&rgba);
    }
    let (position, orientation) = pose_parts(&DAffine3::from_translation(origin));
    PointCloud {
        timestamp: Some(timestamp(stamp_ns)),
        frame_id,
        pose: Some(Pose {
            position: Some(position),
            orientation: Some(orientation),
        }),
        point_stride: POINT_STRIDE,
        fields: fields(),
        data: Bytes::from(data),
    }
}

/// A bin's map in its bin frame (`frame_id`), every Gaussian a point.
pub fn bin_cloud(set: &GaussianSet, frame_id: String, stamp_ns: i64) -> PointCloud {
    let n = set.len();
    let points = (0..n).map(|i| {
        let color = set.colors.get(i).copied().unwrap_or(Vec3::ZERO);
        let opacity = set.opacities.get(i).copied().unwrap_or(0.0);
        (set.means[i], rgba8(color, opacity))
    });
    cloud(frame_id, stamp_ns, DVec3::ZERO, points)
}

/// Gaussians the fused map took in, in the world frame (`frame_id`), relative to `origin`
/// (the bin's origin: world positions are f64, a cloud's points f32).
pub fn world_cloud(
    added: &[WorldGaussian],
    frame_id: String,
    origin: DVec3,
    stamp_ns: i64,
) -> PointCloud {
    let points = added
        .iter()
        .map(|g| ((g.position - origin).as_vec3(), rgba8(g.color, g.opacity)));
    cloud(frame_id, stamp_ns, origin, points)
}

/// An image as 8-bit RGB (values clamped to [0, 1] and rounded).
pub fn raw_image(img: &RgbImage, frame_id: String, stamp_ns: i64) -> RawImage {
    RawImage {
        timestamp: Some(timestamp(stamp_ns)),
        frame_id,
        width: img.width,
        height: img.height,
        encoding: "rgb8".into(),
        step: img.width.saturating_mul(3),
        data: Bytes::from(img.to_rgb8()),
    }
}

/// Where `child` is in `parent`: `child_to_parent` as Foxglove's transform (the same
/// convention as tf2's: the child frame's pose in the parent frame).
pub fn frame_transform(
    parent: &str,
    child: String,
    child_to_parent: &DAffine3,
    stamp_ns: i64,
) -> FrameTransform {
    let (translation, rotation) = pose_parts(child_to_parent);
    FrameTransform {
        timestamp: Some(timestamp(stamp_ns)),
        parent_frame_id: parent.into(),
        child_frame_id: child,
        translation: Some(translation),
        rotation: Some(rotation),
    }
}

/// Milliseconds from `from` to `to` (ns stamps), or null when either was not reached.
fn span_ms(from: i64, to: i64) -> Value {
    match from > 0 && to > 0 {
        true => json!((to - from) as f64 / 1e6),
        false => Value::Null,
    }
}

/// A bin's latency as JSON (see [`LATENCY_SCHEMA`]).
pub fn latency_json(l: &BinLatency) -> Value {
    json!({
        "bin_id": l.bin_id,
        "arrival_to_publish_ms": span_ms(l.first_frame_arrival_ns, l.publish_ns),
        "queue_ms": span_ms(l.first_frame_arrival_ns, l.model_start_ns),
        "model_ms": span_ms(l.model_start_ns, l.model_end_ns),
        "render_ms": span_ms(l.model_end_ns, l.render_end_ns),
        "map_fusion_ms": span_ms(l.model_end_ns, l.map_fused_ns),
        "publish_ms": span_ms(l.map_fused_ns, l.publish_ns),
        "publish_before_close_ms": span_ms(l.publish_ns, l.bin_close_ns),
        "queue_depth": l.queue_depth,
        "drops": l.drops,
        "check_verdict": l.check_verdict,
        "operating_point": l.operating_point,
    })
}

/// The JSON Schema of [`latency_json`]: Foxglove's plot panel reads the fields' types from it.
pub const LATENCY_SCHEMA: &str = r#"{
  "title": "stereosplat.BinLatency",
  "description": "One bin's latency through the node, ms; null where a stage was not reached",
  "type": "object",
  "properties": {
    "bin_id": {"type": "integer"},
    "arrival_to_publish_ms": {"type": ["number", "null"], "description": "the bin's first frame complete to its map published"},
    "queue_ms": {"type": ["number", "null"], "description": "first frame complete to the model's start"},
    "model_ms": {"type": ["number", "null"], "description": "the reconstructor and the self-check"},
    "render_ms": {"type": ["number", "null"], "description": "the render from the input view"},
    "map_fusion_ms": {"type": ["number", "null"], "description": "model end to the map fused into the global map and journaled"},
    "publish_ms": {"type": ["number", "null"], "description": "map fused to the bin's messages published"},
    "publish_before_close_ms": {"type": ["number", "null"], "description": "map published this long before the bin's last frame arrived"},
    "queue_depth": {"type": "integer"},
    "drops": {"type": "integer"},
    "check_verdict": {"type": "integer"},
    "operating_point": {"type": "string", "description": "the operating point the bin's map was made with"}
  }
}"#;

/// The counters as JSON (see [`COUNTERS_SCHEMA`]).
pub fn counters_json(counters: &Counters, stamp_ns: i64) -> Value {
    json!({ "stamp_ns": stamp_ns, "counters": counters })
}

/// The JSON Schema of [`counters_json`].
pub const COUNTERS_SCHEMA: &str = r#"{
  "title": "stereosplat.Counters",
  "description": "The node's counters (bad input, drops, self-checks, Foxglove queue), as on its diagnostics topic",
  "type": "object",
  "properties": {
    "stamp_ns": {"type": "integer"},
    "counters": {"type": "object", "additionalProperties": {"type": "integer"}}
  }
}"#;

/// The JSON Schema of a fused-map increment's summary ([`super::Foxglove::map_increment`]).
pub const INCREMENT_SCHEMA: &str = r#"{
  "title": "stereosplat.MapIncrement",
  "description": "What one bin changed in the fused map: Gaussians added (the points on the new-points topic) and removed, and the map's size after",
  "type": "object",
  "properties": {
    "bin_id": {"type": "integer"},
    "sequence": {"type": "integer"},
    "added": {"type": "integer"},
    "removed": {"type": "integer"},
    "total": {"type": "integer"}
  }
}"#;

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, Quat};

    fn decode(c: &PointCloud) -> Vec<([f32; 3], [u8; 4])> {
        c.data
            .chunks_exact(POINT_STRIDE as usize)
            .map(|p| {
                let f = |i: usize| f32::from_le_bytes(p[i..i + 4].try_into().unwrap());
                ([f(0), f(4), f(8)], [p[12], p[13], p[14], p[15]])
            })
            .collect()
    }

    #[test]
    fn a_bin_map_becomes_points_with_clamped_rounded_colours() {
        let mut set = GaussianSet::with_capacity(3);
        for (mean, color, opacity) in [
            (Vec3::new(1.0, -2.0, 3.5), Vec3::new(0.5, 0.0, 1.0), 0.25),
            // Outside [0, 1]: clamped; NaN colour: black.
            (
                Vec3::new(0.0, 0.0, 1e6),
                Vec3::new(-3.0, 7.0, f32::NAN),
                2.0,
            ),
            (Vec3::splat(f32::MAX), Vec3::new(0.4, 0.6, 0.001), 0.0),
        ] {
            set.means.push(mean);
            set.colors.push(color);
            set.opacities.push(opacity);
            set.log_scales.push(Vec3::ZERO);
            set.rotations.push(Quat::IDENTITY);
            set.confidences.push(1.0);
        }
        let c = bin_cloud(&set, "bin_4".into(), 1_500_000_000_250);
        assert_eq!(c.frame_id, "bin_4");
        assert_eq!(c.point_stride, 16);
        assert_eq!(c.data.len(), 48);
        let t = c.timestamp.unwrap();
        assert_eq!((t.sec(), t.nsec()), (1500, 250));
        let names: Vec<&str> = c.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["x", "y", "z", "red", "green", "blue", "alpha"]);
        let pts = decode(&c);
        assert_eq!(pts[0], ([1.0, -2.0, 3.5], [128, 0, 255, 64]));
        assert_eq!(pts[1], ([0.0, 0.0, 1e6], [0, 255, 0, 255]));
        assert_eq!(pts[2], ([f32::MAX; 3], [102, 153, 0, 0]));
    }

    #[test]
    fn an_empty_map_is_an_empty_cloud_with_its_fields() {
        let c = bin_cloud(&GaussianSet::default(), "bin_0".into(), 0);
        assert!(c.data.is_empty());
        assert_eq!(c.fields.len(), 7);
        let c = world_cloud(&[], "world".into(), DVec3::ZERO, -5);
        assert!(c.data.is_empty());
        assert_eq!(c.timestamp.unwrap().sec(), 0);
    }

    #[test]
    fn world_points_far_from_the_origin_keep_millimetres_through_the_pose() {
        let origin = DVec3::new(1.0e5, -2.0e5, 30.0);
        let g = WorldGaussian {
            position: origin + DVec3::new(0.001, 2.5, -0.003),
            log_scale: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            opacity: 1.0,
            color: Vec3::new(1.0, 0.5, 0.0),
            confidence: 1.0,
            bin_id: 3,
        };
        let c = world_cloud(&[g], "world".into(), origin, 7);
        let p = c.pose.unwrap().position.unwrap();
        assert_eq!((p.x, p.y, p.z), (1.0e5, -2.0e5, 30.0));
        let (xyz, rgba) = decode(&c)[0];
        let back = DVec3::new(p.x, p.y, p.z) + Vec3::from(xyz).as_dvec3();
        assert!((back - g.position).length() < 1e-6, "{back}");
        assert_eq!(rgba, [255, 128, 0, 255]);
    }

    #[test]
    fn a_frame_transform_is_the_child_pose_in_the_parent() {
        let rot = DMat3::from_rotation_z(0.5);
        let pose = DAffine3::from_mat3_translation(rot, DVec3::new(10.0, 20.0, 1.5));
        let t = frame_transform("world", "bin_2".into(), &pose, 42);
        assert_eq!(
            (t.parent_frame_id.as_str(), t.child_frame_id.as_str()),
            ("world", "bin_2")
        );
        let v = t.translation.unwrap();
        assert_eq!((v.x, v.y, v.z), (10.0, 20.0, 1.5));
        let q = t.rotation.unwrap();
        let want = DQuat::from_rotation_z(0.5);
        assert!((q.z - want.z).abs() < 1e-12 && (q.w - want.w).abs() < 1e-12);
    }

    #[test]
    fn stamps_outside_foxglove_s_range_saturate() {
        assert_eq!(timestamp(-1).total_nanos(), 0);
        assert_eq!(timestamp(i64::MAX).sec(), u32::MAX);
    }

    #[test]
    fn latency_spans_are_milliseconds_and_null_when_a_stage_was_not_reached() {
        let l = BinLatency {
            bin_id: 7,
            first_frame_arrival_ns: 1_000_000_000,
            model_start_ns: 1_002_000_000,
            model_end_ns: 1_052_500_000,
            publish_ns: 1_060_000_000,
            operating_point: "tiny-scale0.5".into(),
            ..BinLatency::default()
        };
        let v = latency_json(&l);
        assert_eq!(v["operating_point"], "tiny-scale0.5");
        assert_eq!(v["arrival_to_publish_ms"], 60.0);
        assert_eq!(v["queue_ms"], 2.0);
        assert_eq!(v["model_ms"], 50.5);
        assert!(v["render_ms"].is_null() && v["publish_before_close_ms"].is_null());
        for schema in [LATENCY_SCHEMA, COUNTERS_SCHEMA, INCREMENT_SCHEMA] {
            let s: Value = serde_json::from_str(schema).unwrap();
            assert_eq!(s["type"], "object");
        }
    }
}
