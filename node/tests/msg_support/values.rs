//! The samples of [`super::samples`] as plain JSON field values (what the Python interop
//! scripts build messages from and decode them to), and hex for payloads.

use node::msg::geometry_msgs::{PoseStamped, TransformStamped};
use node::msg::latency::{BinLatency, Counter, Diagnostics};
use node::msg::map_update::MapUpdate;
use node::msg::sensor_msgs::{CameraInfo, Image, PointCloud2, PointField};
use node::msg::std_msgs::Header;
use node::msg::tf2_msgs::TfMessage;
use node::msg::{CdrWriter, Message};
use serde_json::{json, Value};

use super::Samples;

/// Lower-case hex of a payload.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The bytes of a hex string.
pub fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

/// A `Header` as its JSON field values.
pub fn header(h: &Header) -> Value {
    json!({"stamp": {"sec": h.stamp.sec, "nanosec": h.stamp.nanosec}, "frame_id": h.frame_id})
}

/// An `Image` as its JSON field values.
pub fn image(m: &Image) -> Value {
    json!({"header": header(&m.header), "height": m.height, "width": m.width,
           "encoding": m.encoding, "is_bigendian": m.is_bigendian, "step": m.step,
           "data": m.data})
}

/// A `CameraInfo` as its JSON field values.
pub fn camera_info(m: &CameraInfo) -> Value {
    let r = m.roi;
    json!({"header": header(&m.header), "height": m.height, "width": m.width,
           "distortion_model": m.distortion_model, "d": m.d, "k": m.k, "r": m.r, "p": m.p,
           "binning_x": m.binning_x, "binning_y": m.binning_y,
           "roi": {"x_offset": r.x_offset, "y_offset": r.y_offset, "height": r.height,
                   "width": r.width, "do_rectify": r.do_rectify}})
}

/// A `PoseStamped` as its JSON field values.
pub fn pose(m: &PoseStamped) -> Value {
    let (p, q) = (m.pose.position, m.pose.orientation);
    json!({"header": header(&m.header), "pose": {
        "position": {"x": p.x, "y": p.y, "z": p.z},
        "orientation": {"x": q.x, "y": q.y, "z": q.z, "w": q.w}}})
}

/// A `PointField` as its JSON field values.
pub fn point_field(f: &PointField) -> Value {
    json!({"name": f.name, "offset": f.offset, "datatype": f.datatype, "count": f.count})
}

/// A `PointCloud2` as its JSON field values.
pub fn cloud(m: &PointCloud2) -> Value {
    let fields: Vec<_> = m.fields.iter().map(point_field).collect();
    json!({"header": header(&m.header), "height": m.height, "width": m.width,
           "fields": fields, "is_bigendian": m.is_bigendian, "point_step": m.point_step,
           "row_step": m.row_step, "data": m.data, "is_dense": m.is_dense})
}

/// A `BinLatency` as its JSON field values.
pub fn latency(m: &BinLatency) -> Value {
    json!({"bin_id": m.bin_id, "first_frame_arrival_ns": m.first_frame_arrival_ns,
           "bin_close_ns": m.bin_close_ns, "model_start_ns": m.model_start_ns,
           "model_end_ns": m.model_end_ns, "render_end_ns": m.render_end_ns,
           "publish_ns": m.publish_ns, "queue_depth": m.queue_depth, "drops": m.drops,
           "bad_messages": m.bad_messages, "check_verdict": m.check_verdict,
           "check_action": m.check_action, "fallback_verdict": m.fallback_verdict,
           "check_samples": m.check_samples, "check_score": m.check_score,
           "fallback_score": m.fallback_score, "base_end_ns": m.base_end_ns,
           "pseudo_render_end_ns": m.pseudo_render_end_ns, "enhance_end_ns": m.enhance_end_ns,
           "plus_end_ns": m.plus_end_ns, "fuse_end_ns": m.fuse_end_ns,
           "operating_point": m.operating_point, "map_fused_ns": m.map_fused_ns})
}

/// A `Diagnostics` as its JSON field values.
pub fn diagnostics(m: &Diagnostics) -> Value {
    let counters: Vec<_> = m
        .counters
        .iter()
        .map(|c: &Counter| json!({"kind": c.kind, "count": c.count}))
        .collect();
    json!({"stamp_ns": m.stamp_ns, "counters": counters})
}

/// A `MapUpdate` as its JSON field values.
pub fn map_update(m: &MapUpdate) -> Value {
    json!({"header": header(&m.header), "sequence": m.sequence, "snapshot": m.snapshot,
           "bin_id": m.bin_id, "ids": m.ids, "source_bins": m.source_bins,
           "removed_ids": m.removed_ids, "gaussians": cloud(&m.gaussians)})
}

/// A `TransformStamped` as its JSON field values.
pub fn transform_stamped(t: &TransformStamped) -> Value {
    let (p, q) = (t.transform.translation, t.transform.rotation);
    json!({"header": header(&t.header), "child_frame_id": t.child_frame_id, "transform": {
        "translation": {"x": p.x, "y": p.y, "z": p.z},
        "rotation": {"x": q.x, "y": q.y, "z": q.z, "w": q.w}}})
}

/// A `TFMessage` as its JSON field values.
pub fn tf(m: &TfMessage) -> Value {
    let transforms: Vec<_> = m.transforms.iter().map(transform_stamped).collect();
    json!({ "transforms": transforms })
}

/// The reader scripts' "decode" requests for `cases`: each type with its payload in hex.
pub fn decode_requests(cases: &[(&'static str, Vec<u8>, Value)]) -> Vec<Value> {
    cases
        .iter()
        .map(|(t, b, _)| json!({"type": t, "hex": hex(b)}))
        .collect()
}

/// Every sample as (ROS type name, our payload, the field values we mean).
pub fn cases(s: &Samples) -> Vec<(&'static str, Vec<u8>, Value)> {
    vec![
        (Image::KIND.ros_name(), s.image.encode(), image(&s.image)),
        (
            CameraInfo::KIND.ros_name(),
            s.camera_info.encode(),
            camera_info(&s.camera_info),
        ),
        (PoseStamped::KIND.ros_name(), s.pose.encode(), pose(&s.pose)),
        (
            PointCloud2::KIND.ros_name(),
            s.cloud.encode(),
            cloud(&s.cloud),
        ),
        (
            PointCloud2::KIND.ros_name(),
            s.world_cloud.encode(),
            cloud(&s.world_cloud),
        ),
        (
            BinLatency::KIND.ros_name(),
            s.latency.encode(),
            latency(&s.latency),
        ),
        (
            Diagnostics::KIND.ros_name(),
            s.diagnostics.encode(),
            diagnostics(&s.diagnostics),
        ),
        (
            MapUpdate::KIND.ros_name(),
            s.map_update.encode(),
            map_update(&s.map_update),
        ),
        (TfMessage::KIND.ros_name(), s.tf.encode(), tf(&s.tf)),
    ]
}

/// Decodes `bytes` as the type of case `i` of [`cases`] and asserts it equals that sample.
pub fn decodes_to_case(i: usize, bytes: &[u8], s: &Samples, what: &str) {
    match i {
        0 => assert_eq!(Image::decode(bytes).unwrap(), s.image, "{what}"),
        1 => assert_eq!(CameraInfo::decode(bytes).unwrap(), s.camera_info, "{what}"),
        2 => assert_eq!(PoseStamped::decode(bytes).unwrap(), s.pose, "{what}"),
        3 => assert_eq!(PointCloud2::decode(bytes).unwrap(), s.cloud, "{what}"),
        4 => assert_eq!(PointCloud2::decode(bytes).unwrap(), s.world_cloud, "{what}"),
        5 => assert_eq!(BinLatency::decode(bytes).unwrap(), s.latency, "{what}"),
        6 => assert_eq!(Diagnostics::decode(bytes).unwrap(), s.diagnostics, "{what}"),
        7 => assert_eq!(MapUpdate::decode(bytes).unwrap(), s.map_update, "{what}"),
        _ => assert_eq!(TfMessage::decode(bytes).unwrap(), s.tf, "{what}"),
    }
}

/// The payload of `m` with its alignment padding filled with `pad`.
fn padded_with<M: Message>(m: &M, pad: u8) -> Vec<u8> {
    let mut w = CdrWriter::with_padding(pad);
    m.write(&mut w);
    w.into_bytes()
}

/// The payloads of [`cases`] with alignment padding filled with `pad` (where they differ from
/// [`cases`]' zero-padded payloads is padding).
pub fn padded_cases(s: &Samples, pad: u8) -> Vec<Vec<u8>> {
    vec![
        padded_with(&s.image, pad),
        padded_with(&s.camera_info, pad),
        padded_with(&s.pose, pad),
        padded_with(&s.cloud, pad),
        padded_with(&s.world_cloud, pad),
        padded_with(&s.latency, pad),
        padded_with(&s.diagnostics, pad),
        padded_with(&s.map_update, pad),
        padded_with(&s.tf, pad),
    ]
}
