//! Interop with a CDR implementation no one here wrote: `scripts/cdr_decode.py` runs the
//! Python `rosbags` package (ROS 2 Jazzy type store). What the node encodes, rosbags
//! decodes to the same field values; what rosbags encodes (little and big endian), the node
//! decodes to the same values; rosbags' own RIHS01 hashes equal ours, for the node's custom
//! messages too (registered from the same `.msg` texts).
//!
//! Needs `python3` with the packages of `scripts/requirements.txt`; without them the test
//! fails and says how to install them.

use crate::msg_support;
use crate::python_support;

use msg_support::values::{cases, decode_requests, decodes_to_case, unhex};
use msg_support::{gaussians, samples, FAR};
use node::msg::{type_hash, MessageKind};
use renderer::ply::SH_C0;
use serde_json::{json, Value};

const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/cdr_decode.py");

/// Sends one request to the script and returns its reply.
fn rosbags(request: &Value) -> Value {
    python_support::require("rosbags, numpy");
    python_support::run_json(&["python3", SCRIPT], request)
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
    let decode = decode_requests(&cases);
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
        decodes_to_case(i % cases.len(), &b, &s, &what);
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
