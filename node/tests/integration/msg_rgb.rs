//! The packed `rgb` channel of the node's Gaussian clouds, read by ROS 2's own Python stack:
//! `scripts/pointcloud2_rgb.py` deserializes the node's CDR bytes with rclpy (ROS 2 Jazzy's
//! typesupport from the `ros-jazzy-*` wheels) and reads `x y z rgb` with `read_points` of the
//! `pointcloud2` package (a standalone port of ROS 2's `sensor_msgs_py.point_cloud2`, which
//! has no wheel), unpacking `rgb` as the PCL/ROS convention says (the FLOAT32's bits as
//! `0x00RRGGBB`). Checked for a bin cloud (FLOAT32 positions) and a world cloud (FLOAT64
//! positions 100 km out): positions as written, colours equal to the SH DC colour clamped to
//! [0, 1] and rounded to 8 bits, colours outside [0, 1] and NaN included.
//!
//! Needs the wheels of `scripts/requirements.txt` and `scripts/ros2_msgs.sh` run once (CI does
//! both in `.ci/setup`); without them the test fails and says how to get them.

use crate::msg_support::FAR;
use crate::python_support;

use glam::{DVec3, Quat, Vec3};
use node::msg::gaussians::{cloud_from_gaussians, FIELD_NAMES, RGB_FIELD};
use node::msg::std_msgs::Header;
use node::msg::Message;
use renderer::{Gaussian, GaussianSet};
use serde_json::{json, Value};

const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/pointcloud2_rgb.py");

/// Gaussians whose colours cover the clamping and rounding cases: in range, either side of a
/// rounding half, below 0, above 1, NaN.
fn coloured() -> GaussianSet {
    let colours = [
        Vec3::new(0.0, 0.5, 1.0),
        Vec3::new(0.25, 0.75, 0.1),
        Vec3::new(-0.3, 1.7, 0.5),
        Vec3::new(127.4 / 255.0, 0.6 / 255.0, 254.4 / 255.0),
        Vec3::new(f32::NAN, 0.91, -1e9),
    ];
    let mut set = GaussianSet::default();
    for (i, c) in colours.into_iter().enumerate() {
        let f = i as f32;
        set.push(Gaussian {
            mean: Vec3::new(0.5 * f - 1.0, 2.0 - f, 5.0 + f),
            log_scale: Vec3::splat(-3.0),
            rotation: Quat::IDENTITY,
            opacity: 0.8,
            color: c,
            confidence: 1.0,
        });
    }
    set
}

/// The 8-bit value a colour channel must show: clamped to [0, 1], times 255, rounded half up
/// (NaN shows as 0), computed here independently of the node's code.
fn want_u8(c: f32) -> u64 {
    if c.is_nan() {
        return 0;
    }
    (c.clamp(0.0, 1.0) as f64 * 255.0 + 0.5).floor() as u64
}

#[test]
fn ros2_read_points_unpacks_the_colours_we_pack() {
    python_support::require_ros2("rclpy, sensor_msgs.msg, pointcloud2, numpy");
    let set = coloured();
    let bin = cloud_from_gaussians(&set, Header::new(7, "bin_3"), None).unwrap();
    let world = cloud_from_gaussians(&set, Header::new(7, "world"), Some(FAR)).unwrap();
    assert_eq!((bin.point_step, world.point_step), (64, 76));
    let hex = |bytes: Vec<u8>| bytes.iter().map(|b| format!("{b:02x}")).collect::<String>();
    let reply = python_support::run_json(
        &["bash", python_support::ROS2_ENV, "python3", SCRIPT],
        &json!({"clouds": [hex(bin.encode()), hex(world.encode())]}),
    );

    let mut names: Vec<&str> = FIELD_NAMES.to_vec();
    names.push(RGB_FIELD);
    for (k, origin) in [DVec3::ZERO, FAR].into_iter().enumerate() {
        let fields: Vec<&str> = reply["fields"][k]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_str().unwrap())
            .collect();
        assert_eq!(
            fields, names,
            "cloud {k}: the 3DGS fields stay, rgb comes last"
        );
        let points = reply["points"][k].as_array().expect("points");
        assert_eq!(points.len(), set.len());
        for (i, p) in points.iter().enumerate() {
            let p: Vec<f64> = p
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let m = origin + set.means[i].as_dvec3();
            // FLOAT32 positions in the bin frame are the f32 means; FLOAT64 world ones exact.
            for (axis, (got, want)) in p[..3].iter().zip(m.to_array()).enumerate() {
                assert_eq!(*got, want, "cloud {k} point {i} axis {axis}");
            }
            let c = set.colors[i];
            let want = [want_u8(c.x), want_u8(c.y), want_u8(c.z)];
            let got = [p[3] as u64, p[4] as u64, p[5] as u64];
            assert_eq!(got, want, "cloud {k} point {i}: colour {c}");
        }
    }
    // The cases the colours were chosen for, spelled out.
    let first: Vec<Value> = reply["points"][0].as_array().unwrap().to_vec();
    let rgb = |i: usize| [3, 4, 5].map(|j| first[i][j].as_u64().unwrap());
    assert_eq!(rgb(0), [0, 128, 255]);
    assert_eq!(rgb(2), [0, 255, 128]);
    assert_eq!(rgb(3), [127, 1, 254]);
    assert_eq!(rgb(4), [0, 232, 0]);
}
