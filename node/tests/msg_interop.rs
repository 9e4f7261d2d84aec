//! Interop with a CDR implementation no one here wrote: `scripts/cdr_decode.py` runs the
//! Python `rosbags` package (ROS 2 Jazzy type store). What the node encodes, rosbags
//! decodes to the same field values; what rosbags encodes (little and big endian), the node
//! decodes to the same values; rosbags' own RIHS01 hashes equal ours, for the node's custom
//! messages too (registered from the same `.msg` texts).
//!
//! Needs `python3` with the packages of `scripts/requirements.txt`; without them the test
//! fails and says how to install them.

mod msg_support;
mod python_support;

use std::io::Write;
use std::process::{Command, Stdio};

use msg_support::{gaussians, samples, Samples, FAR};
use node::msg::geometry_msgs::PoseStamped;
use node::msg::latency::{BinLatency, Counter, Diagnostics};
use node::msg::map_update::MapUpdate;
use node::msg::sensor_msgs::{CameraInfo, Image, PointCloud2, PointField};
use node::msg::std_msgs::Header;
use node::msg::{type_hash, Message, MessageKind};
use renderer::ply::SH_C0;
use serde_json::{json, Value};

const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/cdr_decode.py");

/// Sends one request to the script and returns its reply.
fn rosbags(request: &Value) -> Value {
    python_support::require("rosbags, numpy");
    let mut child = Command::new("python3")
        .arg(SCRIPT)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 starts");
    let body = serde_json::to_vec(request).expect("request serialises");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(&body)
        .expect("request written");
    let out = child.wait_with_output().expect("script runs");
    assert!(
        out.status.success(),
        "cdr_decode.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("the script prints JSON")
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

fn header(h: &Header) -> Value {
    json!({"stamp": {"sec": h.stamp.sec, "nanosec": h.stamp.nanosec}, "frame_id": h.frame_id})
}

fn image(m: &Image) -> Value {
    json!({"header": header(&m.header), "height": m.height, "width": m.width,
           "encoding": m.encoding, "is_bigendian": m.is_bigendian, "step": m.step,
           "data": m.data})
}

fn camera_info(m: &CameraInfo) -> Value {
    let r = m.roi;
    json!({"header": header(&m.header), "height": m.height, "width": m.width,
           "distortion_model": m.distortion_model, "d": m.d, "k": m.k, "r": m.r, "p": m.p,
           "binning_x": m.binning_x, "binning_y": m.binning_y,
           "roi": {"x_offset": r.x_offset, "y_offset": r.y_offset, "height": r.height,
                   "width": r.width, "do_rectify": r.do_rectify}})
}

fn pose(m: &PoseStamped) -> Value {
    let (p, q) = (m.pose.position, m.pose.orientation);
    json!({"header": header(&m.header), "pose": {
        "position": {"x": p.x, "y": p.y, "z": p.z},
        "orientation": {"x": q.x, "y": q.y, "z": q.z, "w": q.w}}})
}

fn point_field(f: &PointField) -> Value {
    json!({"name": f.name, "offset": f.offset, "datatype": f.datatype, "count": f.count})
}

fn cloud(m: &PointCloud2) -> Value {
    let fields: Vec<_> = m.fields.iter().map(point_field).collect();
    json!({"header": header(&m.header), "height": m.height, "width": m.width,
           "fields": fields, "is_bigendian": m.is_bigendian, "point_step": m.point_step,
           "row_step": m.row_step, "data": m.data, "is_dense": m.is_dense})
}

fn latency(m: &BinLatency) -> Value {
    json!({"bin_id": m.bin_id, "first_frame_arrival_ns": m.first_frame_arrival_ns,
           "bin_close_ns": m.bin_close_ns, "model_start_ns": m.model_start_ns,
           "model_end_ns": m.model_end_ns, "render_end_ns": m.render_end_ns,
           "publish_ns": m.publish_ns, "queue_depth": m.queue_depth, "drops": m.drops,
           "bad_messages": m.bad_messages, "check_verdict": m.check_verdict,
           "check_action": m.check_action, "fallback_verdict": m.fallback_verdict,
           "check_samples": m.check_samples, "check_score": m.check_score,
           "fallback_score": m.fallback_score})
}

fn diagnostics(m: &Diagnostics) -> Value {
    let counters: Vec<_> = m
        .counters
        .iter()
        .map(|c: &Counter| json!({"kind": c.kind, "count": c.count}))
        .collect();
    json!({"stamp_ns": m.stamp_ns, "counters": counters})
}

fn map_update(m: &MapUpdate) -> Value {
    json!({"header": header(&m.header), "sequence": m.sequence, "snapshot": m.snapshot,
           "bin_id": m.bin_id, "ids": m.ids, "source_bins": m.source_bins,
           "removed_ids": m.removed_ids, "gaussians": cloud(&m.gaussians)})
}

/// Every sample as (ROS type name, our payload, the field values we mean).
fn cases(s: &Samples) -> Vec<(&'static str, Vec<u8>, Value)> {
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
    ]
}

/// The node's own definitions, registered with rosbags.
fn custom_msgs() -> Value {
    let kinds = [
        MessageKind::BinLatency,
        MessageKind::Counter,
        MessageKind::Diagnostics,
        MessageKind::MapUpdate,
    ];
    Value::Object(
        kinds
            .iter()
            .map(|k| (k.ros_name().to_owned(), json!(k.definition())))
            .collect(),
    )
}

/// Checks the points rosbags + numpy read from a Gaussian cloud against the Gaussians' values
/// in the 3DGS PLY convention; `origin` is added to positions (world clouds).
fn check_points(points: &Value, origin: glam::DVec3) {
    let set = gaussians();
    let get = |name: &str, i: usize| points[name][i].as_f64().expect("a number");
    for i in 0..set.len() {
        let m = set.means[i].as_dvec3() + origin;
        for (name, want) in [("x", m.x), ("y", m.y), ("z", m.z)] {
            let tol = if origin == glam::DVec3::ZERO {
                1e-6
            } else {
                0.0
            };
            assert!(
                (get(name, i) - want).abs() <= tol,
                "{name}[{i}] {} vs {want}",
                get(name, i)
            );
        }
        let c = set.colors[i].as_dvec3();
        let a = set.opacities[i] as f64;
        let q = set.rotations[i];
        let s = set.log_scales[i];
        let want = [
            ("f_dc_0", (c.x - 0.5) / SH_C0),
            ("f_dc_1", (c.y - 0.5) / SH_C0),
            ("f_dc_2", (c.z - 0.5) / SH_C0),
            ("opacity", (a / (1.0 - a)).ln()),
            ("scale_0", s.x as f64),
            ("scale_1", s.y as f64),
            ("scale_2", s.z as f64),
            ("rot_0", q.w as f64),
            ("rot_1", q.x as f64),
            ("rot_2", q.y as f64),
            ("rot_3", q.z as f64),
            ("confidence", set.confidences[i] as f64),
        ];
        for (name, v) in want {
            assert!(
                (get(name, i) - v).abs() < 1e-6,
                "{name}[{i}]: {} vs {v}",
                get(name, i)
            );
        }
    }
}

#[test]
fn rosbags_reads_what_we_write_and_we_read_what_it_writes() {
    let s = samples();
    let cases = cases(&s);
    let decode: Vec<_> = cases
        .iter()
        .map(|(t, b, _)| json!({"type": t, "hex": hex(b)}))
        .collect();
    let encode: Vec<_> = [true, false]
        .iter()
        .flat_map(|&le| {
            cases
                .iter()
                .map(move |(t, _, v)| json!({"type": t, "value": v, "little_endian": le}))
        })
        .collect();
    let hashes: Vec<_> = MessageKind::ALL.iter().map(|k| k.ros_name()).collect();
    let reply = rosbags(
        &json!({"msgs": custom_msgs(), "decode": decode, "encode": encode,
                                "hash": hashes}),
    );

    // Ours -> rosbags: every field as meant.
    let decoded = reply["decoded"].as_array().expect("decoded list");
    assert_eq!(decoded.len(), cases.len());
    for ((t, _, want), got) in cases.iter().zip(decoded) {
        let mut got = got.clone();
        let points = got.as_object_mut().and_then(|o| o.remove("points"));
        let keys = want.as_object().expect("an object").keys();
        for k in keys {
            assert_eq!(got[k], want[k], "{t}.{k} as rosbags decodes it");
        }
        assert_eq!(&got, want, "{t} as rosbags decodes it");
        if let Some(points) = points {
            let world = got["header"]["frame_id"] == "world";
            check_points(&points, if world { FAR } else { glam::DVec3::ZERO });
        }
    }

    // rosbags -> ours, little then big endian: the same messages.
    let encoded = reply["encoded"].as_array().expect("encoded list");
    assert_eq!(encoded.len(), 2 * cases.len());
    for (i, e) in encoded.iter().enumerate() {
        let b = unhex(e.as_str().expect("hex string"));
        assert_eq!(
            b[1],
            if i < cases.len() { 1 } else { 0 },
            "encapsulation of {i}"
        );
        let what = format!("{} from rosbags (payload {i})", cases[i % cases.len()].0);
        match i % cases.len() {
            0 => assert_eq!(Image::decode(&b).unwrap(), s.image, "{what}"),
            1 => assert_eq!(CameraInfo::decode(&b).unwrap(), s.camera_info, "{what}"),
            2 => assert_eq!(PoseStamped::decode(&b).unwrap(), s.pose, "{what}"),
            3 => assert_eq!(PointCloud2::decode(&b).unwrap(), s.cloud, "{what}"),
            4 => assert_eq!(PointCloud2::decode(&b).unwrap(), s.world_cloud, "{what}"),
            5 => assert_eq!(BinLatency::decode(&b).unwrap(), s.latency, "{what}"),
            6 => assert_eq!(Diagnostics::decode(&b).unwrap(), s.diagnostics, "{what}"),
            _ => assert_eq!(MapUpdate::decode(&b).unwrap(), s.map_update, "{what}"),
        }
        // Little-endian payloads are byte for byte ours, up to rosbags' end padding.
        if i < cases.len() {
            let ours = &cases[i].1;
            assert_eq!(&b[..ours.len()], &ours[..], "{what}: bytes");
            assert!(b[ours.len()..].iter().all(|&x| x == 0) && b.len() - ours.len() < 4);
        }
    }

    // rosbags computes the same type hashes, for the node's own messages too.
    for kind in MessageKind::ALL {
        assert_eq!(
            reply["hashes"][kind.ros_name()],
            json!(type_hash(kind)),
            "{kind:?}"
        );
    }
}
