//! The node's rectification against OpenCV's, which ROS's `image_proc` runs:
//! `scripts/rectify_vs_opencv.py` computes `cv2.initUndistortRectifyMap` (the fisheye one
//! for `equidistant`) and `cv2.remap` (INTER_LINEAR, BORDER_CONSTANT 0) for the same
//! calibrations and raw images; the node's table must agree to a mean of 0.05 px (the
//! product's bound) and 1e-3 px everywhere, its rectified images to one level, rarely.
//! Measured with OpenCV 5.0.0: the maps equal to 2e-10 px, a handful of bytes of each image
//! one level apart (PSNR 99 to 105 dB).
//!
//! Needs `python3` with the packages of `scripts/requirements.txt` (opencv-python-headless,
//! numpy); without them the test fails and says how to install them.

use std::path::{Path, PathBuf};

use model::frame::Rgb8Image;
use node::msg::sensor_msgs::CameraInfo;
use node::rectify::{CameraModel, RemapTable};
use serde_json::json;

use crate::python_support;

const SCRIPT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scripts/rectify_vs_opencv.py"
);

/// A row-major rotation of `degrees` about `axis` (normalised first).
fn rotation(axis: [f64; 3], degrees: f64) -> [f64; 9] {
    let axis = glam::DVec3::from(axis).normalize();
    // glam is column major: its transpose's columns are the rows.
    glam::DMat3::from_axis_angle(axis, degrees.to_radians())
        .transpose()
        .to_cols_array()
}

/// A calibration of the given parts.
fn camera(
    (width, height): (u32, u32),
    model: &str,
    d: &[f64],
    [fx, fy, cx, cy]: [f64; 4],
    r: [f64; 9],
    [pf, pcx, pcy, tx]: [f64; 4],
) -> CameraInfo {
    CameraInfo {
        width,
        height,
        distortion_model: model.to_owned(),
        d: d.to_vec(),
        k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
        r,
        p: [pf, 0.0, pcx, tx, 0.0, pf, pcy, 0.0, 0.0, 0.0, 1.0, 0.0],
        ..CameraInfo::default()
    }
}

/// A KITTI-like wide stereo pair (1408x376, 0.54 m, rectification turns of about a
/// degree) and VGA cameras of each model.
fn cameras() -> Vec<(&'static str, CameraInfo)> {
    let d = [-0.344, 0.142, 4e-4, -2e-4, 0.0];
    let p = [700.0, 704.0, 188.0];
    vec![
        (
            "kitti_left",
            camera(
                (1408, 376),
                "plumb_bob",
                &d,
                [788.6, 786.4, 700.2, 187.8],
                rotation([0.4, 1.0, 0.1], 0.8),
                [p[0], p[1], p[2], 0.0],
            ),
        ),
        (
            "kitti_right",
            camera(
                (1408, 376),
                "plumb_bob",
                &[-0.341, 0.139, -3e-4, 5e-4, 0.0],
                [790.1, 787.9, 708.9, 190.3],
                rotation([0.2, 1.0, -0.3], 1.3),
                [p[0], p[1], p[2], -p[0] * 0.54],
            ),
        ),
        (
            "vga_plumb_bob",
            camera(
                (640, 480),
                "plumb_bob",
                &[-0.28, 0.07, 5e-4, -3e-4, 0.01],
                [500.0, 501.0, 321.0, 238.5],
                rotation([1.0, -0.5, 0.2], 1.5),
                [470.0, 318.0, 242.0, 0.0],
            ),
        ),
        (
            "vga_rational_polynomial",
            camera(
                (640, 480),
                "rational_polynomial",
                &[0.8, -0.2, 1e-4, -2e-4, 0.05, 1.1, -0.05, 0.1],
                [500.0, 502.0, 321.0, 238.5],
                rotation([0.3, -1.0, 0.2], 1.5),
                [430.0, 318.0, 242.0, 0.0],
            ),
        ),
        (
            "vga_equidistant",
            camera(
                (640, 480),
                "equidistant",
                &[-0.01, 0.05, -0.08, 0.04],
                [300.0, 300.5, 319.5, 240.5],
                rotation([0.3, -1.0, 0.2], 1.5),
                [250.0, 320.0, 240.0, 0.0],
            ),
        ),
    ]
}

/// A texture with detail down to 7 px (so small map differences show in the image).
fn textured(width: u32, height: u32) -> Rgb8Image {
    let tau = std::f64::consts::TAU;
    let data = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x as f64, y as f64)))
        .flat_map(|(x, y)| {
            (0..3).map(move |c| {
                let c = c as f64;
                let v = 128.0
                    + 50.0 * (tau * x / 31.0 + c).sin()
                    + 40.0 * (tau * (x - y) / 13.0 + 2.0 * c).sin()
                    + 30.0 * (tau * y / 7.0 + 3.0 * c).cos();
                v.round().clamp(0.0, 255.0) as u8
            })
        })
        .collect();
    Rgb8Image {
        width,
        height,
        data,
    }
}

fn scratch(name: &str) -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("rectify-opencv-{name}"))
}

fn read_f32(path: &str) -> Vec<f32> {
    std::fs::read(path)
        .expect("the script wrote its map")
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

#[test]
fn tables_and_images_match_opencv() {
    python_support::require("cv2, numpy");
    let cameras = cameras();
    let mut request = Vec::new();
    let mut ours = Vec::new();
    for (name, info) in &cameras {
        let model = CameraModel::from_camera_info(info).expect(name);
        let raw = RemapTable::distort(&model)
            .remap(&textured(info.width, info.height))
            .unwrap();
        let raw_path = scratch(&format!("{name}.raw.rgb"));
        std::fs::write(&raw_path, &raw.data).unwrap();
        request.push(json!({
            "name": name, "width": info.width, "height": info.height,
            "distortion_model": info.distortion_model, "d": info.d, "k": info.k,
            "r": info.r, "p": info.p,
            "raw": raw_path, "out": scratch(name),
        }));
        let table = RemapTable::rectify(&model);
        let rectified = table.remap(&raw).unwrap();
        ours.push((table, rectified));
    }
    let reply = python_support::run_json(&["python3", SCRIPT], &json!({ "cameras": request }));
    for ((name, _), ((table, rectified), theirs)) in cameras
        .iter()
        .zip(ours.iter().zip(reply["cameras"].as_array().unwrap()))
    {
        let file = |key: &str| theirs[key].as_str().expect(key).to_owned();
        let (map_x, map_y) = (read_f32(&file("map_x")), read_f32(&file("map_y")));
        assert_eq!(map_x.len(), table.coordinates().len(), "{name}");
        let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
        for (i, [x, y]) in table.coordinates().iter().enumerate() {
            let (dx, dy) = ((x - map_x[i]) as f64, (y - map_y[i]) as f64);
            assert!(dx.is_finite() && dy.is_finite(), "{name}: pixel {i}");
            let e = dx.hypot(dy);
            sum += e;
            max = max.max(e);
            n += 1;
        }
        let mean = sum / n as f64;
        let cv = std::fs::read(file("rectified")).unwrap();
        let diffs: Vec<u8> = rectified
            .data
            .iter()
            .zip(&cv)
            .map(|(a, b)| a.abs_diff(*b))
            .collect();
        let mean_abs = diffs.iter().map(|d| *d as f64).sum::<f64>() / diffs.len() as f64;
        let mse = diffs.iter().map(|d| (*d as f64).powi(2)).sum::<f64>() / diffs.len() as f64;
        let psnr = 10.0 * (255.0f64.powi(2) / mse.max(1e-12)).log10();
        let worst = diffs.iter().max().copied().unwrap_or(0);
        let differ = diffs.iter().filter(|d| **d > 0).count();
        eprintln!(
            "{name} ({}x{}, OpenCV {}): map mean {mean:.2e} px, max {max:.2e} px; image mean abs {mean_abs:.2e}, max {worst}, {differ} of {} bytes differ, PSNR {psnr:.1} dB",
            table.width(),
            table.height(),
            reply["opencv"],
            diffs.len(),
        );
        assert!(mean <= 0.05, "{name}: mean map difference {mean} px");
        assert!(max <= 1e-3, "{name}: largest map difference {max} px");
        assert!(worst <= 1, "{name}: {worst} levels from OpenCV's remap");
        assert!(psnr >= 80.0, "{name}: {psnr} dB against OpenCV's remap");
    }
}
