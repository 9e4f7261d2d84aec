//! `stereosplat reconstruct` as a user runs it: a generated pair gives the promised files and
//! a depth close to the generator's LiDAR truth (flags and camera-info YAML alike); each bad
//! input gives its own clear error; a raw, distorted pair with its cameras' full YAMLs gives
//! the rectified pair's depth; all-black and all-white pairs give finite results; on
//! the real Aloe pair (scripts/real_data.sh) SGM keeps its measured bad-3 and the learned
//! model's scores are finite.

use std::path::{Path, PathBuf};
use std::process::Command;

use model::frame::Side;
use model::kitti360::Sequence;

use crate::cli_support;
use crate::node_image_transports::RawRig;

use cli_support::{stereosplat, temp_dir};

/// A one-frame generated drive at 272x72: its left and right image paths and the sequence.
pub(crate) fn synthetic_pair(name: &str) -> (PathBuf, PathBuf, Sequence) {
    let data = temp_dir(name);
    stereosplat(
        &[
            "research", "synth", "--frames", "1", "--width", "272", "--height", "72", "--out",
        ],
        &[&data],
    );
    let seq_name = Sequence::list(&data).unwrap().remove(0);
    let seq = Sequence::open(&data, &seq_name).unwrap();
    let image = |cam: &str| {
        data.join("data_2d_raw")
            .join(&seq_name)
            .join(cam)
            .join("data_rect/0000000000.png")
    };
    (image("image_00"), image("image_01"), seq)
}

/// The rig flags of a sequence.
pub(crate) fn rig_flags(seq: &Sequence) -> Vec<String> {
    let rig = seq.rig();
    let k = rig.intrinsics;
    [
        ("--fx", k.fx as f64),
        ("--fy", k.fy as f64),
        ("--cx", k.cx as f64),
        ("--cy", k.cy as f64),
        ("--baseline", rig.baseline),
    ]
    .iter()
    .flat_map(|(f, v)| [f.to_string(), v.to_string()])
    .collect()
}

/// Runs `reconstruct` with `args`; (success, stdout + stderr).
fn reconstruct(args: &[String]) -> (bool, String) {
    let run = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
        .arg("reconstruct")
        .args(args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&run.stdout).to_string() + &String::from_utf8_lossy(&run.stderr);
    (run.status.success(), text)
}

fn strings(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| s.to_string()).collect()
}

fn pair_args(left: &Path, right: &Path, out: &Path) -> Vec<String> {
    let p = |p: &Path| p.display().to_string();
    vec![
        "--left".into(),
        p(left),
        "--right".into(),
        p(right),
        "--out".into(),
        p(out),
    ]
}

/// `depth.png` in metres (16-bit, metres x 256, 0 = none).
fn read_depth(path: &Path) -> (u32, u32, Vec<f32>) {
    let img = image::open(path).unwrap().to_luma16();
    let depth = img.as_raw().iter().map(|v| *v as f32 / 256.0).collect();
    (img.width(), img.height(), depth)
}

/// `depth.npy` (format 1.0, little-endian float32): its shape and values.
fn read_depth_npy(path: &Path) -> ((usize, usize), Vec<f32>) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let header_end = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert_eq!(header_end % 64, 0);
    let header = std::str::from_utf8(&bytes[10..header_end]).unwrap();
    assert!(
        header.contains("'descr': '<f4'") && header.ends_with('\n'),
        "{header}"
    );
    let shape = header
        .split("'shape': (")
        .nth(1)
        .unwrap()
        .split(')')
        .next()
        .unwrap();
    let dims: Vec<usize> = shape
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect();
    let values = bytes[header_end..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    ((dims[0], dims[1]), values)
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

/// Every number in a JSON value is finite (serde_json writes NaN and infinities as null,
/// so a null where a number belongs is what a NaN looks like).
fn assert_finite(v: &serde_json::Value, path: &str) {
    match v {
        serde_json::Value::Number(n) => assert!(n.as_f64().unwrap().is_finite(), "{path}"),
        serde_json::Value::Array(a) => a
            .iter()
            .enumerate()
            .for_each(|(i, x)| assert_finite(x, &format!("{path}[{i}]"))),
        serde_json::Value::Object(o) => o
            .iter()
            .for_each(|(k, x)| assert_finite(x, &format!("{path}.{k}"))),
        _ => {}
    }
}

/// Median relative depth error and coverage of `depth` at the LiDAR truth's pixels.
fn against_lidar(depth: &[f32], truth: &[f32]) -> (f32, f32) {
    let mut rel: Vec<f32> = depth
        .iter()
        .zip(truth)
        .filter(|(d, t)| **d > 0.0 && **t > 0.0)
        .map(|(d, t)| (d - t).abs() / t)
        .collect();
    let known = truth.iter().filter(|t| **t > 0.0).count();
    let coverage = rel.len() as f32 / known.max(1) as f32;
    let mid = rel.len() / 2;
    (*rel.select_nth_unstable_by(mid, f32::total_cmp).1, coverage)
}

#[test]
fn a_generated_pair_gives_the_files_and_its_depth() {
    let (left, right, seq) = synthetic_pair("reconstruct-synth");
    let truth = seq.lidar_depth(0, Side::Left).unwrap();
    for method in ["sgm", "stereosplat"] {
        let out = temp_dir(&format!("reconstruct-synth-{method}"));
        let mut args = pair_args(&left, &right, &out);
        args.extend(rig_flags(&seq));
        args.extend(strings(&["--method", method]));
        let (ok, text) = reconstruct(&args);
        assert!(ok, "{text}");
        for file in [
            "gaussians.ply",
            "depth.png",
            "depth.npy",
            "depth_color.png",
            "render.png",
            "photometric_error.png",
            "summary.json",
        ] {
            assert!(out.join(file).is_file(), "{method}: no {file}");
        }
        let (w, h, depth) = read_depth(&out.join("depth.png"));
        assert_eq!((w, h), (272, 72));
        // The float depth is the PNG's before its 1/256-m rounding.
        let (shape, floats) = read_depth_npy(&out.join("depth.npy"));
        assert_eq!(shape, (72, 272));
        assert!(floats
            .iter()
            .zip(&depth)
            .all(|(f, p)| (f - p).abs() <= 0.5 / 256.0 + 1e-6));
        let (median_rel, coverage) = against_lidar(&depth, &truth.data);
        println!(
            "{method}: median relative depth error {median_rel:.3}, LiDAR coverage {coverage:.2}"
        );
        assert!(median_rel < 0.1, "{method}: {median_rel}");
        assert!(coverage > 0.5, "{method}: {coverage}");
        let s = summary(&out);
        assert_finite(&s, method);
        assert_eq!(s["check"]["verdict"], "pass", "{method}: {}", s["check"]);
        assert_eq!(s["check"]["action"], "none");
        assert_eq!(s["depth_rule"], "surface", "the default depth rule");
        assert!(s["gaussians"].as_u64().unwrap() > 1000);
        let ply = renderer::ply::load_ply(out.join("gaussians.ply")).unwrap();
        assert_eq!(ply.len() as u64, s["gaussians"].as_u64().unwrap());
        // A street reaches beyond the preset's 50-m bound on the fitted far end
        // (`auto_depth_range_max_far`): no fit; the learned model reports the candidates
        // its rig calls for, on KITTI-360's rig the 1-100 m the weights learned.
        match method {
            "sgm" => assert!(s["depth_range_m"].is_null(), "{}", s["depth_range_m"]),
            _ => {
                let range = s["depth_range_m"].as_array().expect("the rig's range");
                let near = range[0].as_f64().unwrap();
                let far = range[1].as_f64().unwrap();
                assert!(
                    (near - 1.0).abs() < 2e-3 && (far - 100.0).abs() < 0.2,
                    "{range:?}"
                );
            }
        }
    }
}

#[test]
fn auto_depth_range_fits_the_aloe_pair_and_is_reported() {
    // A bound of 50 m on the fitted far end (`auto_depth_range_max_far`) lets the room
    // through; one of 5 m, under the room's depth, keeps the rig's range.
    let mut ranges = Vec::new();
    for max_far in ["50", "5"] {
        let out = temp_dir(&format!("reconstruct-aloe-auto-range-{max_far}"));
        let bound = format!("auto_depth_range_max_far={max_far}");
        let args = aloe_args(&out, &learned_flagged(&["auto_depth_range=true", &bound]));
        let (ok, text) = reconstruct(&args);
        assert!(ok, "{text}");
        let s = summary(&out);
        assert_finite(&s, "auto range");
        ranges.push(s["depth_range_m"].clone());
    }
    // The truth spans 1.8..8.3 m; SGM's 2nd-98th percentiles with a 25% margin, inside
    // the preset's 1..100 m (measured: 2.12..10.24 m; the nearest leaves, 1.8-2.1 m, fall
    // outside it, a cost of trusting percentiles).
    let range = ranges[0].as_array().expect("a fitted range");
    let (near, far) = (range[0].as_f64().unwrap(), range[1].as_f64().unwrap());
    assert!((1.0..2.5).contains(&near), "{near}..{far}");
    assert!((7.0..20.0).contains(&far), "{near}..{far}");
    // Unfitted, the candidates are the rig's: fx 1315.7 px x 0.1 m at the 451-px working
    // width over 0.233181 x 451 px is 1.251 m, to 100 times that.
    let rig = ranges[1].as_array().expect("the rig's range");
    assert!((rig[0].as_f64().unwrap() - 1.251).abs() < 2e-3, "{rig:?}");
    assert!((rig[1].as_f64().unwrap() / rig[0].as_f64().unwrap() - 100.0).abs() < 1e-3);
}

#[test]
fn a_swapped_pair_fails_the_self_check_and_sgm_replaces_the_learned_map() {
    let (left, right, seq) = synthetic_pair("reconstruct-swapped");
    let mut results = Vec::new();
    for policy in ["sgm", "flag"] {
        let out = temp_dir(&format!("reconstruct-swapped-{policy}"));
        // Left and right swapped: no depth explains the pair.
        let mut args = pair_args(&right, &left, &out);
        args.extend(rig_flags(&seq));
        args.extend(strings(&[
            "--method",
            "stereosplat",
            "--on-check-fail",
            policy,
        ]));
        let (ok, text) = reconstruct(&args);
        assert!(ok, "{text}");
        let s = summary(&out);
        assert_finite(&s, policy);
        let check = s["check"].clone();
        println!("{policy}: {check}");
        assert_eq!(check["verdict"], "fail", "{check}");
        assert!(check["score"].as_f64().unwrap() < 0.6);
        results.push((check, s["gaussians"].as_u64().unwrap()));
    }
    let (sgm, flag) = (&results[0].0, &results[1].0);
    assert_eq!(sgm["action"], "sgm");
    assert!(
        sgm["fallback"].is_array(),
        "SGM's own check is reported: {sgm}"
    );
    assert_eq!(flag["action"], "flagged");
    assert_eq!(flag["flagged"], true);
    assert!(flag["fallback"].is_null());
    assert_ne!(
        results[0].1, results[1].1,
        "the SGM map was written, not the learned one"
    );
}

/// A ROS camera_calibration YAML with the rectified projection `P` (fx, fy, cx, cy, Tx).
fn camera_yaml(path: &Path, size: (u32, u32), p: [f64; 5]) {
    let [fx, fy, cx, cy, tx] = p;
    let text = format!(
        "image_width: {}\nimage_height: {}\ncamera_name: cam\ncamera_matrix:\n  rows: 3\n  cols: 3\n  \
         data: [{fx}, 0, {cx}, 0, {fy}, {cy}, 0, 0, 1]\ndistortion_model: plumb_bob\n\
         distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n\
         rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n\
         projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{fx}, 0, {cx}, {tx}, 0, {fy}, {cy}, 0, 0, 0, 1, 0]\n",
        size.0, size.1
    );
    std::fs::write(path, text).unwrap();
}

/// A ROS camera_calibration YAML of `info`'s K, D, R and P.
fn full_camera_yaml(path: &Path, info: &node::msg::sensor_msgs::CameraInfo) {
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:e}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let text = format!(
        "image_width: {}\nimage_height: {}\ncamera_name: cam\ncamera_matrix:\n  rows: 3\n  \
         cols: 3\n  data: [{}]\ndistortion_model: {}\ndistortion_coefficients:\n  rows: 1\n  \
         cols: {}\n  data: [{}]\nrectification_matrix:\n  rows: 3\n  cols: 3\n  data: [{}]\n\
         projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{}]\n",
        info.width,
        info.height,
        list(&info.k),
        info.distortion_model,
        info.d.len(),
        list(&info.d),
        list(&info.r),
        list(&info.p),
    );
    std::fs::write(path, text).unwrap();
}

/// AbsRel of `depth` against `reference` where both have a depth, and the share of the
/// reference's depths that `depth` has.
fn abs_rel_against(depth: &[f32], reference: &[f32]) -> (f64, f64) {
    let both: Vec<f64> = depth
        .iter()
        .zip(reference)
        .filter(|(d, r)| **d > 0.0 && **r > 0.0)
        .map(|(d, r)| ((d - r).abs() / r) as f64)
        .collect();
    let known = reference.iter().filter(|r| **r > 0.0).count();
    (
        both.iter().sum::<f64>() / both.len().max(1) as f64,
        both.len() as f64 / known.max(1) as f64,
    )
}

#[test]
fn a_raw_pair_with_its_cameras_yamls_gives_the_rectified_pairs_depth() {
    let (left, right, seq) = synthetic_pair("reconstruct-raw");
    let dir = temp_dir("reconstruct-raw-files");
    std::fs::create_dir_all(&dir).unwrap();
    let rig = seq.rig();
    let lenses = RawRig::behind_lenses(&rig);
    let raw_png = |side: usize, rectified: &Path, name: &str| {
        let img = image::open(rectified).unwrap().to_rgb8();
        let img = model::frame::RgbImage::from_rgb8(img.width(), img.height(), img.as_raw());
        let raw = lenses.raw(side, &img);
        let path = dir.join(name);
        image::RgbImage::from_raw(raw.width, raw.height, raw.to_rgb8())
            .unwrap()
            .save(&path)
            .unwrap();
        path
    };
    let (raw_left, raw_right) = (
        raw_png(0, &left, "left.png"),
        raw_png(1, &right, "right.png"),
    );
    let yamls = [dir.join("left.yaml"), dir.join("right.yaml")];
    for (path, info) in yamls.iter().zip(&lenses.infos) {
        full_camera_yaml(path, info);
    }
    let k = rig.intrinsics;
    let (fx, fy, cx, cy) = (k.fx as f64, k.fy as f64, k.cx as f64, k.cy as f64);
    let rectified_yamls = [dir.join("rect_left.yaml"), dir.join("rect_right.yaml")];
    camera_yaml(&rectified_yamls[0], (272, 72), [fx, fy, cx, cy, 0.0]);
    camera_yaml(
        &rectified_yamls[1],
        (272, 72),
        [fx, fy, cx, cy, -fx * rig.baseline],
    );
    let run = |name: &str, (l, r): (&Path, &Path), files: &[PathBuf; 2], extra: &[&str]| {
        let out = dir.join(name);
        let mut args = pair_args(l, r, &out);
        let p = |p: &Path| p.display().to_string();
        args.extend(["--camera-info".into(), p(&files[0])]);
        args.extend(["--camera-info-right".into(), p(&files[1])]);
        args.extend(strings(&["--method", "sgm"]));
        args.extend(strings(extra));
        let (ok, text) = reconstruct(&args);
        assert!(ok, "{name}: {text}");
        read_depth_npy(&out.join("depth.npy")).1
    };
    let reference = run("rectified", (&left, &right), &rectified_yamls, &[]);
    let rectified = run("raw", (&raw_left, &raw_right), &yamls, &[]);
    let unrectified = run(
        "raw-as-is",
        (&raw_left, &raw_right),
        &yamls,
        &["--pre-rectified"],
    );
    let (abs_rel, coverage) = abs_rel_against(&rectified, &reference);
    let (as_is, _) = abs_rel_against(&unrectified, &reference);
    println!(
        "raw pair rectified by its YAMLs: depth AbsRel {abs_rel:.4} against the rectified \
         pair's ({coverage:.2} of its depths); taken as rectified: {as_is:.4}"
    );
    assert!(abs_rel < 0.08 && coverage > 0.9, "{abs_rel} {coverage}");
    assert!(as_is > 2.0 * abs_rel, "{as_is} against {abs_rel}");
    // A raw left camera without the right one's file cannot be rectified.
    let out = dir.join("alone");
    let mut args = pair_args(&raw_left, &raw_right, &out);
    args.extend(strings(&["--camera-info", &yamls[0].display().to_string()]));
    args.extend(strings(&["--baseline", "0.6", "--method", "sgm"]));
    let (ok, text) = reconstruct(&args);
    assert!(!ok && text.contains("--camera-info-right"), "{text}");
}

#[test]
fn camera_info_yaml_and_every_bad_input_give_their_result() {
    let (left, right, seq) = synthetic_pair("reconstruct-errors");
    let dir = temp_dir("reconstruct-errors-files");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("out");
    let rig = seq.rig();
    let k = rig.intrinsics;
    let (fx, fy, cx, cy) = (k.fx as f64, k.fy as f64, k.cx as f64, k.cy as f64);
    let (left_yaml, right_yaml, bad_yaml) = (
        dir.join("left.yaml"),
        dir.join("right.yaml"),
        dir.join("bad.yaml"),
    );
    camera_yaml(&left_yaml, (272, 72), [fx, fy, cx, cy, 0.0]);
    camera_yaml(&right_yaml, (272, 72), [fx, fy, cx, cy, -fx * rig.baseline]);
    camera_yaml(
        &bad_yaml,
        (272, 72),
        [fx * 1.1, fy, cx, cy, -fx * rig.baseline],
    );
    let base = |extra: &[&str]| {
        let mut args = pair_args(&left, &right, &out);
        args.extend(strings(&["--method", "sgm"]));
        args.extend(strings(extra));
        args
    };
    let path = |p: &Path| p.display().to_string();

    // The YAML pair: the baseline comes from the right camera's P[0,3].
    let (ok, text) = reconstruct(&base(&[
        "--camera-info",
        &path(&left_yaml),
        "--camera-info-right",
        &path(&right_yaml),
    ]));
    assert!(ok, "{text}");
    let b = summary(&out)["baseline_m"].as_f64().unwrap();
    assert!((b - rig.baseline).abs() < 1e-6 * rig.baseline, "{b}");

    let fails = |args: Vec<String>, expected: &str| {
        let (ok, text) = reconstruct(&args);
        assert!(!ok, "{expected}: succeeded");
        assert!(text.contains(expected), "{expected}: {text}");
    };
    let baseline = rig.baseline.to_string();
    fails(
        base(&["--baseline", &baseline]),
        "missing calibration: no focal length",
    );
    fails(base(&["--fx", "300"]), "missing calibration: no baseline");
    fails(
        base(&["--fx=-300", "--baseline", "0.5"]),
        "inconsistent calibration",
    );
    fails(
        base(&["--fx", "300", "--baseline", "0"]),
        "inconsistent calibration",
    );
    fails(
        base(&[
            "--camera-info",
            &path(&left_yaml),
            "--camera-info-right",
            &path(&bad_yaml),
        ]),
        "inconsistent calibration: the rectified projections differ in fx'",
    );
    fails(
        base(&[
            "--camera-info",
            &path(&left_yaml),
            "--camera-info-right",
            &path(&right_yaml),
            "--baseline",
            "9",
        ]),
        "inconsistent calibration: --baseline 9 m",
    );
    std::fs::write(&bad_yaml, "image_width: [").unwrap();
    fails(
        base(&["--camera-info", &path(&bad_yaml), "--baseline", "1"]),
        "is not a ROS camera_calibration YAML file",
    );

    // Sizes: a right image of another size; a calibration for another size.
    let small = dir.join("small.png");
    image::RgbImage::new(100, 40).save(&small).unwrap();
    let mut args = pair_args(&left, &small, &out);
    args.extend(strings(&["--fx", "300", "--baseline", "0.5"]));
    fails(args, "left and right images: 272x72 against 100x40");
    calibration_size_mismatch(&left, &right, &out, &dir, [fx, fy, cx, cy]);

    // A right image shifted 6 rows down: not rectified, refused with the measured number.
    let shifted = dir.join("shifted.png");
    let img = image::open(&right).unwrap().to_rgb8();
    let moved = image::RgbImage::from_fn(img.width(), img.height(), |x, y| {
        *img.get_pixel(x, y.saturating_sub(6))
    });
    moved.save(&shifted).unwrap();
    let mut args = pair_args(&left, &shifted, &out);
    args.extend(rig_flags(&seq));
    let (ok, text) = reconstruct(&args);
    assert!(!ok && text.contains("does not look rectified"), "{text}");
    let measured: f32 = text
        .split("patches match ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{text}"));
    assert!((measured - 6.0).abs() < 1.0, "{measured}");
}

/// A camera-info YAML for 544x144 against 272x72 images is a size mismatch.
fn calibration_size_mismatch(left: &Path, right: &Path, out: &Path, dir: &Path, k: [f64; 4]) {
    let yaml = dir.join("big.yaml");
    camera_yaml(&yaml, (544, 144), [k[0], k[1], k[2], k[3], 0.0]);
    let mut args = pair_args(left, right, out);
    args.extend(strings(&[
        "--camera-info",
        &yaml.display().to_string(),
        "--baseline",
        "0.5",
    ]));
    let (ok, text) = reconstruct(&args);
    assert!(
        !ok && text.contains("calibration and images: 544x144 against 272x72"),
        "{text}"
    );
}

#[test]
fn black_and_white_pairs_give_finite_results() {
    let dir = temp_dir("reconstruct-extremes");
    std::fs::create_dir_all(&dir).unwrap();
    for (name, value) in [("black", 0u8), ("white", 255u8)] {
        let path = dir.join(format!("{name}.png"));
        image::GrayImage::from_pixel(160, 120, image::Luma([value]))
            .save(&path)
            .unwrap();
        for method in ["sgm", "stereosplat"] {
            let out = dir.join(format!("{name}-{method}"));
            let mut args = pair_args(&path, &path, &out);
            args.extend(strings(&[
                "--fx",
                "150",
                "--baseline",
                "0.3",
                "--method",
                method,
            ]));
            let (ok, text) = reconstruct(&args);
            assert!(ok, "{name} {method}: {text}");
            let s = summary(&out);
            assert_finite(&s, &format!("{name} {method}"));
            // Nothing to match: the rectification check has no answer, and no answer is
            // not a refusal.
            assert!(s["vertical_input_px"].is_null(), "{name} {method}");
            let (_, _, depth) = read_depth(&out.join("depth.png"));
            assert!(depth.iter().all(|d| d.is_finite() && *d >= 0.0));
            if method == "sgm" {
                // SGM finds no match in a uniform image and says so: no depth at all.
                assert_eq!(s["depth_density"].as_f64().unwrap(), 0.0, "{name}");
            }
        }
    }
}

/// The Aloe pair installed by scripts/real_data.sh.
fn aloe() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/real/aloe");
    assert!(
        dir.join("aloeGT.png").is_file(),
        "no Aloe pair in {}: run `bash scripts/real_data.sh` (part of .ci/setup)",
        dir.display()
    );
    dir
}

/// The learned model's own output (`--on-check-fail flag`) with `settings` (`KEY=VALUE`).
fn learned_flagged<'a>(settings: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["--method", "stereosplat", "--on-check-fail", "flag"];
    for setting in settings {
        args.extend(["--set", setting]);
    }
    args
}

/// `reconstruct` arguments for the Aloe pair (and its calibration) into `out`, then `extra`.
fn aloe_args(out: &Path, extra: &[&str]) -> Vec<String> {
    let data = aloe();
    let mut args = pair_args(&data.join("aloeL.jpg"), &data.join("aloeR.jpg"), out);
    args.extend(strings(&["--fx", "3740", "--baseline", "0.1"]));
    args.extend(strings(extra));
    args
}

#[test]
fn real_aloe_pair_sgm_keeps_its_score_and_the_learned_one_is_finite() {
    let data = aloe();
    for method in ["sgm", "stereosplat"] {
        let out = temp_dir(&format!("reconstruct-aloe-{method}"));
        let mut args = aloe_args(&out, &["--method", method]);
        args.extend([
            "--truth-disparity".into(),
            data.join("aloeGT.png").display().to_string(),
        ]);
        let (ok, text) = reconstruct(&args);
        assert!(ok, "{method}: {text}");
        let s = summary(&out);
        assert_finite(&s, method);
        let t = &s["truth"];
        for key in ["bad1", "bad3", "epe", "density", "bad3_predicted"] {
            assert!(t[key].is_number(), "{method} {key}: {t}");
        }
        println!("{method}: {t}");
        let check = &s["check"];
        println!("{method}: self-check {check}");
        // The learned model's self-check score on this real pair lies near the threshold
        // (0.6 passes; `bash scripts/real_pairs.sh` reports it): when it fails, by default
        // SGM's reconstruction is written instead.
        let replaced = check["verdict"] == "fail" && check["action"] == "sgm";
        if method == "stereosplat" {
            assert!(check["verdict"] == "pass" || replaced, "{check}");
        }
        if method == "sgm" || replaced {
            // Measured 17.62% bad-3 (85.9% density), 2.02 px EPE at the default working size.
            assert!(t["bad3"].as_f64().unwrap() < 19.0, "{t}");
            assert!(t["density"].as_f64().unwrap() > 85.0, "{t}");
            assert!(t["epe"].as_f64().unwrap() < 3.0, "{t}");
        }
        assert!(out.join("disparity_error.png").is_file());
    }
}

#[test]
fn sgm_guidance_brings_the_learned_model_closer_to_the_aloe_truth() {
    // The shipped tiny guides its depth head with SGM's matches on near scenes: on Aloe the
    // hints must take several points of bad-3 and over a pixel and a half of EPE off the run
    // without them (both runs print their scores; SGM scores 17.0% bad-3).
    let data = aloe();
    let mut scores = Vec::new();
    for guidance in ["10", "null"] {
        let out = temp_dir(&format!("reconstruct-aloe-guidance-{guidance}"));
        let setting = format!("sgm_guidance={guidance}");
        let mut args = aloe_args(&out, &learned_flagged(&[&setting]));
        args.extend([
            "--truth-disparity".into(),
            data.join("aloeGT.png").display().to_string(),
        ]);
        let (ok, text) = reconstruct(&args);
        assert!(ok, "{guidance}: {text}");
        let s = summary(&out);
        assert_finite(&s, &setting);
        let t = &s["truth"];
        println!("{setting}: {t}");
        scores.push((t["bad3"].as_f64().unwrap(), t["epe"].as_f64().unwrap()));
    }
    let ((guided_bad3, guided_epe), (plain_bad3, plain_epe)) = (scores[0], scores[1]);
    assert!(
        guided_bad3 < 52.0 && guided_bad3 < plain_bad3 - 5.0,
        "{scores:?}"
    );
    assert!(guided_epe < plain_epe - 1.5, "{scores:?}");
}
