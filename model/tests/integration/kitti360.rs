//! The KITTI-360 layout reader and writer: round trips, the published calibration, LiDAR
//! projection, files in the real format, and one test per kind of bad input.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DAffine3, DQuat, DVec3};
use model::frame::{RgbImage, Side, StereoFrame};
use model::kitti360::{layout, Calibration, Kitti360Error, Sequence, SequenceWriter};

const SEQ: &str = "2013_05_28_drive_0000_sync";
/// 1408x376 divided by 16 (height rounded): small enough for fast tests.
const W: u32 = 88;
const H: u32 = 24;
/// 2013-05-28 08:46:02.482785814 UTC, a KITTI-360 capture time.
const T0: i64 = 1_369_730_762_482_785_814;

/// A fresh directory no other test (or run) shares.
fn temp_root(name: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!(
        "stereosplat-kitti360-{}-{n}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An image whose values are exact 8-bit levels, different per frame and side.
fn pattern(width: u32, height: u32, seed: u32) -> RgbImage {
    let bytes: Vec<u8> = (0..3 * width * height)
        .map(|i| ((i * 7 + seed * 31) % 256) as u8)
        .collect();
    RgbImage::from_rgb8(width, height, &bytes)
}

fn pose(yaw: f64, t: DVec3) -> DAffine3 {
    DAffine3::from_rotation_translation(
        DQuat::from_rotation_y(yaw) * DQuat::from_rotation_x(0.1),
        t,
    )
}

fn frame(index: u32, left_to_world: DAffine3) -> StereoFrame {
    StereoFrame {
        index,
        left: pattern(W, H, 2 * index),
        right: pattern(W, H, 2 * index + 1),
        left_to_world,
    }
}

/// Three frames, the last 100 km from the origin, with scans; returns the frames.
fn write_sequence(root: &Path) -> Vec<StereoFrame> {
    let calib = Calibration::synthetic(W, H);
    let mut writer = SequenceWriter::create(root, SEQ, &calib).unwrap();
    let frames = vec![
        frame(0, DAffine3::IDENTITY),
        frame(1, pose(0.3, DVec3::new(1.5, -0.2, 7.9))),
        frame(
            2,
            pose(-2.0, DVec3::new(1.0e5, -1.0e5 + 0.123456789, 123.456789012)),
        ),
    ];
    for f in &frames {
        writer
            .write_frame(f, T0 + f.index as i64 * 103_000_000)
            .unwrap();
        let scan = [[f.index as f32, 2.0, -0.5, 0.25], [10.0, -1.0, 0.5, 0.75]];
        writer
            .write_lidar(f.index, &scan, T0 + 50 + f.index as i64 * 100_000_000)
            .unwrap();
    }
    writer.finish().unwrap();
    frames
}

fn max_diff(a: &DAffine3, b: &DAffine3) -> f64 {
    let (a, b) = (a.to_cols_array(), b.to_cols_array());
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

#[test]
fn calibration_round_trips_through_its_files() {
    let root = temp_root("calib");
    let calib = Calibration::synthetic(W, H);
    calib.write(&root).unwrap();
    let back = Calibration::read(&root).unwrap();
    assert_eq!(back.image_size, (W, H));
    for (a, b) in calib
        .p_rect_01
        .iter()
        .flatten()
        .zip(back.p_rect_01.iter().flatten())
    {
        assert!((a - b).abs() <= 1e-12 * a.abs().max(1.0), "{a} vs {b}");
    }
    assert!(max_diff(&calib.cam_to_velo, &back.cam_to_velo) < 1e-12);
    assert!(max_diff(&calib.cam_to_pose[1], &back.cam_to_pose[1]) < 1e-12);
    assert!((back.r_rect_00 - calib.r_rect_00).abs_diff_eq(glam::DMat3::ZERO, 1e-15));
}

#[test]
fn synthetic_calibration_is_kitti360_scaled() {
    let full = Calibration::synthetic(1408, 376).rig().unwrap();
    assert!((full.intrinsics.fx as f64 - 552.554261).abs() < 1e-3);
    assert!((full.intrinsics.cx as f64 - 682.049453).abs() < 1e-3);
    assert!((full.intrinsics.cy as f64 - 238.769549).abs() < 1e-3);
    assert!(
        (full.baseline - 0.594_183).abs() < 1e-5,
        "{}",
        full.baseline
    );
    let half = Calibration::synthetic(704, 188).rig().unwrap();
    let scaled = full.intrinsics.scaled(704, 188);
    assert!((half.intrinsics.fx - 276.277_13).abs() < 1e-3);
    assert!((half.intrinsics.cx - scaled.cx).abs() < 1e-3);
    assert!((half.intrinsics.cy - scaled.cy).abs() < 1e-3);
    assert!((half.baseline - full.baseline).abs() < 1e-12);
    // Rectified-exact: camera 1 sits the baseline along camera 0's x in the pose frame.
    let c = Calibration::synthetic(704, 188);
    let rel = c.cam_to_pose[0].inverse() * c.cam_to_pose[1];
    assert!((rel.translation - DVec3::X * half.baseline).length() < 1e-9);
}

#[test]
fn sequence_round_trips_frames_poses_lidar_and_timestamps() {
    let root = temp_root("roundtrip");
    let frames = write_sequence(&root);
    let seq = Sequence::open(&root, SEQ).unwrap();
    assert_eq!(Sequence::list(&root).unwrap(), vec![SEQ.to_string()]);
    assert_eq!(seq.frames().len(), 3);
    assert!(seq.skipped().is_empty());
    assert!(seq.pose_file().ends_with("cam0_to_world.txt"));
    for (f, p) in frames.iter().zip(seq.frames()) {
        assert_eq!(p.index, f.index);
        assert_eq!(p.timestamp_ns, Some(T0 + f.index as i64 * 103_000_000));
        // Far from the origin (1e5 m) the position still survives to well under 1e-6 m.
        assert!(max_diff(&p.left_to_world, &f.left_to_world) < 1e-9);
        let loaded = seq.load_frame(f.index).unwrap();
        assert_eq!(loaded.left, f.left);
        assert_eq!(loaded.right, f.right);
        // As bytes for publishing: the PNGs' own, at the file size.
        let bytes = seq.load_frame_rgb8(f.index).unwrap();
        assert_eq!(
            (bytes.left.width, bytes.left.height),
            (f.left.width, f.left.height)
        );
        assert_eq!(bytes.left.data, f.left.to_rgb8());
        assert_eq!(bytes.right.data, f.right.to_rgb8());
        assert_eq!(bytes.left_to_world, loaded.left_to_world);
        let scan = seq.load_lidar(f.index).unwrap();
        assert_eq!(
            scan,
            vec![[f.index as f32, 2.0, -0.5, 0.25], [10.0, -1.0, 0.5, 0.75]]
        );
    }
    let far = &seq.frames()[2].left_to_world.translation;
    assert!((*far - DVec3::new(1.0e5, -1.0e5 + 0.123456789, 123.456789012)).length() < 1e-6);
    let velo_stamps = std::fs::read_to_string(layout::velodyne_timestamps(&root, SEQ)).unwrap();
    assert_eq!(
        velo_stamps.lines().nth(1),
        Some("2013-05-28 08:46:02.582785864")
    );

    // poses.txt alone gives the same camera poses (devkit: pose * cam_to_pose * R_rect^-1).
    std::fs::remove_file(layout::cam0_to_world(&root, SEQ)).unwrap();
    let from_imu = Sequence::open(&root, SEQ).unwrap();
    assert!(from_imu.pose_file().ends_with("poses.txt"));
    for (a, b) in seq.frames().iter().zip(from_imu.frames()) {
        assert!(max_diff(&a.left_to_world, &b.left_to_world) < 1e-9);
    }

    // Timestamps are optional.
    std::fs::remove_file(layout::image_timestamps(&root, SEQ, Side::Left)).unwrap();
    let no_time = Sequence::open(&root, SEQ).unwrap();
    assert!(no_time.frames().iter().all(|f| f.timestamp_ns.is_none()));
}

#[test]
fn writer_output_is_byte_deterministic() {
    let (a, b) = (temp_root("det-a"), temp_root("det-b"));
    write_sequence(&a);
    write_sequence(&b);
    let files = [
        layout::perspective(&a),
        layout::cam_to_pose(&a),
        layout::cam_to_velo(&a),
        layout::poses(&a, SEQ),
        layout::cam0_to_world(&a, SEQ),
        layout::image(&a, SEQ, Side::Right, 2),
        layout::image_timestamps(&a, SEQ, Side::Left),
        layout::velodyne(&a, SEQ, 1),
    ];
    for fa in files {
        let fb = b.join(fa.strip_prefix(&a).unwrap());
        assert_eq!(
            std::fs::read(&fa).unwrap(),
            std::fs::read(&fb).unwrap(),
            "{}",
            fa.display()
        );
    }
    // A second sequence may share the calibration only if it is identical.
    assert!(SequenceWriter::create(
        &a,
        "2013_05_28_drive_0002_sync",
        &Calibration::synthetic(W, H)
    )
    .is_ok());
    let other = Calibration::synthetic(W + 2, H);
    let err = SequenceWriter::create(&a, "2013_05_28_drive_0003_sync", &other).unwrap_err();
    assert!(
        matches!(err, Kitti360Error::CalibrationConflict { .. }),
        "{err}"
    );
}

/// Sequences started at once in one fresh root (as parallel `synth` runs do) all share the
/// calibration: none reads another's half-written file as a conflict, and no temporary file
/// is left beside the calibration. (Before the writes went through a renamed file, one of
/// 8 threads failed within the first 60 of these rounds.)
#[test]
fn sequences_started_in_parallel_in_one_root_share_its_calibration() {
    let calib = Calibration::synthetic(W, H);
    for round in 0..300 {
        let root = temp_root(&format!("parallel-{round}"));
        let results: Vec<_> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..8)
                .map(|k| {
                    let (root, calib) = (&root, &calib);
                    let seq = format!("2013_05_28_drive_{k:04}_sync");
                    scope.spawn(move || SequenceWriter::create(root, &seq, calib).map(|_| ()))
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        for result in results {
            assert!(result.is_ok(), "round {round}: {}", result.unwrap_err());
        }
        let calibration_dir = layout::perspective(&root).parent().unwrap().to_path_buf();
        let names: Vec<String> = std::fs::read_dir(&calibration_dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names.len(), 3, "{names:?}");
        assert!(names.iter().all(|n| !n.ends_with(".tmp")), "{names:?}");
        std::fs::remove_dir_all(&root).unwrap();
    }
}

#[test]
fn lidar_depth_puts_a_point_ten_metres_ahead_at_its_pixel() {
    let root = temp_root("lidar");
    let calib = Calibration::synthetic(W, H);
    let mut writer = SequenceWriter::create(&root, SEQ, &calib).unwrap();
    writer
        .write_frame(&frame(0, DAffine3::IDENTITY), T0)
        .unwrap();
    // Points given in rectified camera 0, stored in the velodyne frame.
    let to_velo = calib.velo_to_rect().inverse();
    let velo = |p: DVec3| {
        let v = to_velo.transform_point3(p).as_vec3();
        [v.x, v.y, v.z, 0.5]
    };
    let ahead = DVec3::new(1.2, 0.4, 10.0);
    let scan = [
        velo(ahead),
        velo(ahead * 2.0),
        velo(DVec3::new(0.0, 0.0, -10.0)),
    ];
    writer.write_lidar(0, &scan, T0).unwrap();
    writer.finish().unwrap();

    let seq = Sequence::open(&root, SEQ).unwrap();
    let k = seq.rig().intrinsics;
    let (u, v) = (
        k.fx as f64 * 0.12 + k.cx as f64,
        k.fy as f64 * 0.04 + k.cy as f64,
    );
    let left = seq.lidar_depth(0, Side::Left).unwrap();
    let (pu, pv) = (u.round() as u32, v.round() as u32);
    // The nearer of the two points on that ray wins; the one behind the camera is dropped.
    assert!((left.data[(pv * W + pu) as usize] - 10.0).abs() < 1e-4);
    assert_eq!(left.valid_count(), 1);
    // In the right camera the point moves left by fx * baseline / z pixels.
    let right = seq.lidar_depth(0, Side::Right).unwrap();
    let ru = (u - k.fx as f64 * seq.rig().baseline / 10.0).round() as u32;
    assert!(ru < pu);
    assert!((right.data[(pv * W + ru) as usize] - 10.0).abs() < 1e-4);
    // At half resolution the point lands at the scaled pixel.
    let half = Sequence::open(&root, SEQ)
        .unwrap()
        .with_resolution(W / 2, H / 2);
    let hk = half.rig().intrinsics;
    let hu = (hk.fx as f64 * 0.12 + hk.cx as f64).round() as u32;
    let hv = (hk.fy as f64 * 0.04 + hk.cy as f64).round() as u32;
    let depth = half.lidar_depth(0, Side::Left).unwrap();
    assert_eq!((depth.width, depth.height), (W / 2, H / 2));
    assert!((depth.data[(hv * (W / 2) + hu) as usize] - 10.0).abs() < 1e-4);
    let small = half.load_frame(0).unwrap();
    assert_eq!((small.left.width, small.left.height), (W / 2, H / 2));
    // Read at another size, the bytes are the resampled images rounded back to bytes.
    let bytes = half.load_frame_rgb8(0).unwrap();
    assert_eq!((bytes.left.width, bytes.left.height), (W / 2, H / 2));
    assert_eq!(bytes.left.data, small.left.to_rgb8());
    assert_eq!(bytes.right.data, small.right.to_rgb8());
}

/// KITTI-360's calibration in the line shapes of the real files, and one frame's GPS/IMU
/// pose with the camera pose the dataset publishes for it. The values are the published ones
/// as third-party code quotes them (`R_rect`, `K`, `D` to 6 digits), except `image_01` of
/// `calib_cam_to_pose.txt`, which is `image_00` moved by the baseline (the published line was
/// not at hand; the reader does not use it for camera 0 poses).
fn write_real_format(root: &Path) {
    let files = [
        (
            layout::perspective(root),
            "calib_time: 09-Jan-2012 13:57:47\n\
corner_dist: 9.950000e-02\n\
S_00: 1.392000e+03 5.120000e+02\n\
K_00: 7.886293e+02 0.000000e+00 6.871584e+02 0.000000e+00 7.863822e+02 3.177522e+02 0.000000e+00 0.000000e+00 1.000000e+00\n\
D_00: -3.444410e-01 1.416780e-01 4.140000e-04 -2.220000e-04 -2.960800e-02\n\
R_00: 1.000000e+00 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00\n\
T_00: 0.000000e+00 0.000000e+00 0.000000e+00\n\
S_rect_00: 1.408000e+03 3.760000e+02\n\
R_rect_00: 9.999740e-01 -7.141000e-03 -8.900000e-05 7.141000e-03 9.999690e-01 -3.247000e-03 1.120000e-04 3.247000e-03 9.999950e-01\n\
P_rect_00: 5.525543e+02 0.000000e+00 6.820495e+02 0.000000e+00 0.000000e+00 5.525543e+02 2.387695e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n\
S_01: 1.392000e+03 5.120000e+02\n\
K_01: 7.851341e+02 0.000000e+00 6.864371e+02 0.000000e+00 7.823463e+02 3.213528e+02 0.000000e+00 0.000000e+00 1.000000e+00\n\
D_01: -3.531950e-01 1.619960e-01 3.830000e-04 -2.420000e-04 -4.147600e-02\n\
S_rect_01: 1.408000e+03 3.760000e+02\n\
R_rect_01: 9.998370e-01 4.862000e-03 -1.739000e-02 -4.974000e-03 9.999670e-01 -6.389000e-03 1.735800e-02 6.474000e-03 9.998280e-01\n\
P_rect_01: 5.525543e+02 0.000000e+00 6.820495e+02 -3.283187e+02 0.000000e+00 5.525543e+02 2.387695e+02 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n",
        ),
        (
            layout::cam_to_pose(root),
            "image_00: 0.0371783278 -0.0986182135 0.9944306009 1.5752681039 0.9992675562 -0.0053553387 -0.0378902567 0.0043914093 0.0090621821 0.9951109327 0.0983468786 -0.6500000000\n\
image_01: 0.0371783278 -0.0986182135 0.9944306009 1.5973588603 0.9992675562 -0.0053553387 -0.0378902567 0.5981399027 0.0090621821 0.9951109327 0.0983468786 -0.6446153991\n",
        ),
        (
            layout::cam_to_velo(root),
            "0.04307104361 -0.08829286498 0.995162929 0.8043914418 -0.999004371 0.007784614041 0.04392796942 0.2993489574 -0.01162548558 -0.9960641394 -0.08786966659 -0.1770225824\n",
        ),
        (
            layout::poses(root, SEQ),
            "250 0.6804458798 -0.7314378405 0.0446328361 3639.236961 -0.7298356009 -0.6819080306 -0.0483883609 1708.205377 0.0658285676 0.000351028 -0.9978308857 122.056814\n",
        ),
    ];
    for (path, text) in files {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }
    std::fs::create_dir_all(layout::images_root(root).join(SEQ)).unwrap();
}

#[test]
fn reads_files_in_the_real_kitti360_format() {
    let root = temp_root("real");
    write_real_format(&root);
    let seq = Sequence::open(&root, SEQ).unwrap();
    let rig = seq.rig();
    assert_eq!((rig.intrinsics.width, rig.intrinsics.height), (1408, 376));
    assert!((rig.intrinsics.fx - 552.5543).abs() < 1e-3);
    assert!((rig.baseline - 328.3187 / 552.5543).abs() < 1e-9);
    // poses.txt * cam_to_pose * R_rect^-1 gives the cam0_to_world KITTI-360 publishes for
    // this frame: -0.705111 -2.610952e-02 0.708616 3.640277e+03 / -0.709097 2.470034e-02
    // -0.704678 1.707084e+03 / 0.000896 -9.993541e-01 -0.035930 1.228091e+02.
    let published = [
        [-0.705111, -2.610952e-02, 0.708616, 3.640277e+03],
        [-0.709097, 2.470034e-02, -0.704678, 1.707084e+03],
        [0.000896, -9.993541e-01, -0.035930, 1.228091e+02],
    ];
    let got = seq.frames()[0].left_to_world;
    assert_eq!(seq.frames()[0].index, 250);
    for (r, row) in published.iter().enumerate() {
        for (c, want) in row.iter().enumerate() {
            let v = if c == 3 {
                got.translation[r]
            } else {
                got.matrix3.col(c)[r]
            };
            let tol = if c == 3 { 1e-3 } else { 2e-6 };
            assert!((v - want).abs() < tol, "[{r}][{c}] {v} vs {want}");
        }
    }
    // A cam0_to_world.txt line is preferred over poses.txt.
    std::fs::write(
        layout::cam0_to_world(&root, SEQ),
        "250 1 0 0 10 0 1 0 20 0 0 1 30 0 0 0 1\n",
    )
    .unwrap();
    let seq = Sequence::open(&root, SEQ).unwrap();
    assert_eq!(
        seq.frames()[0].left_to_world.translation,
        DVec3::new(10.0, 20.0, 30.0)
    );
}

/// A one-frame sequence ready for breaking.
fn small_sequence(name: &str) -> PathBuf {
    let root = temp_root(name);
    let calib = Calibration::synthetic(W, H);
    let mut writer = SequenceWriter::create(&root, SEQ, &calib).unwrap();
    writer
        .write_frame(&frame(0, DAffine3::IDENTITY), T0)
        .unwrap();
    writer.write_lidar(0, &[[5.0, 0.0, 0.0, 1.0]], T0).unwrap();
    writer.finish().unwrap();
    root
}

#[test]
fn corrupt_png_is_a_png_error_naming_the_file() {
    let root = small_sequence("corrupt-png");
    let path = layout::image(&root, SEQ, Side::Left, 0);
    std::fs::write(&path, b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let err = Sequence::open(&root, SEQ)
        .unwrap()
        .load_frame(0)
        .unwrap_err();
    assert!(
        matches!(&err, Kitti360Error::Png { path: p, .. } if *p == path),
        "{err}"
    );
}

#[test]
fn left_right_size_mismatch_is_refused() {
    let root = small_sequence("size");
    let path = layout::image(&root, SEQ, Side::Right, 0);
    image::RgbImage::new(W - 1, H).save(&path).unwrap();
    let err = Sequence::open(&root, SEQ)
        .unwrap()
        .load_frame(0)
        .unwrap_err();
    match err {
        Kitti360Error::SizeMismatch {
            path: p,
            expected,
            found,
        } => {
            assert_eq!(p, path);
            assert_eq!((expected, found), ((W, H), (W - 1, H)));
        }
        other => panic!("{other}"),
    }
    // Gray PNGs of the right size are accepted and become RGB.
    image::GrayImage::from_pixel(W, H, image::Luma([51]))
        .save(&path)
        .unwrap();
    let f = Sequence::open(&root, SEQ).unwrap().load_frame(0).unwrap();
    assert_eq!(f.right.pixel(3, 3), [0.2, 0.2, 0.2]);
}

#[test]
fn non_finite_pose_is_skipped_and_counted() {
    let root = small_sequence("nan-pose");
    let path = layout::cam0_to_world(&root, SEQ);
    let good = std::fs::read_to_string(&path).unwrap();
    let text =
        format!("{good}1 nan 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n2 1 0 0 inf 0 1 0 0 0 0 1 0 0 0 0 1\n");
    std::fs::write(&path, text).unwrap();
    let seq = Sequence::open(&root, SEQ).unwrap();
    assert_eq!(seq.frames().len(), 1);
    assert_eq!(
        seq.skipped().iter().map(|s| s.index).collect::<Vec<_>>(),
        vec![1, 2]
    );
    let err = seq.load_frame(1).unwrap_err();
    assert!(
        matches!(err, Kitti360Error::UnknownFrame { index: 1, .. }),
        "{err}"
    );
}

#[test]
fn empty_lidar_file_is_an_error() {
    let root = small_sequence("empty-lidar");
    std::fs::write(layout::velodyne(&root, SEQ, 0), b"").unwrap();
    let err = Sequence::open(&root, SEQ)
        .unwrap()
        .load_lidar(0)
        .unwrap_err();
    assert!(matches!(err, Kitti360Error::EmptyLidar { .. }), "{err}");
}

#[test]
fn lidar_length_not_a_multiple_of_16_is_an_error() {
    let root = small_sequence("short-lidar");
    std::fs::write(layout::velodyne(&root, SEQ, 0), [0u8; 20]).unwrap();
    let err = Sequence::open(&root, SEQ)
        .unwrap()
        .lidar_depth(0, Side::Left)
        .unwrap_err();
    assert!(
        matches!(err, Kitti360Error::BadLidarLength { len: 20, .. }),
        "{err}"
    );
}

#[test]
fn missing_frame_file_is_named() {
    let root = small_sequence("missing");
    let path = layout::image(&root, SEQ, Side::Right, 0);
    std::fs::remove_file(&path).unwrap();
    let err = Sequence::open(&root, SEQ)
        .unwrap()
        .load_frame(0)
        .unwrap_err();
    assert!(
        matches!(&err, Kitti360Error::MissingFile { path: p } if *p == path),
        "{err}"
    );
}

#[test]
fn malformed_line_names_file_and_line() {
    let root = small_sequence("malformed");
    let path = layout::cam0_to_world(&root, SEQ);
    let good = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, format!("{good}1 1 0 0 0 0 1 0 0 0 0 1 0\n")).unwrap();
    let err = Sequence::open(&root, SEQ).unwrap_err();
    assert!(
        matches!(&err, Kitti360Error::Parse { path: p, line: 2, .. } if *p == path),
        "{err}"
    );
    assert!(err.to_string().contains("cam0_to_world.txt:2:"), "{err}");
    // So does a bad timestamp line.
    std::fs::write(&path, &good).unwrap();
    let stamps = layout::image_timestamps(&root, SEQ, Side::Left);
    std::fs::write(&stamps, "2013-05-28 08:46:02.482785814\n2013-05-28 8:46\n").unwrap();
    let err = Sequence::open(&root, SEQ).unwrap_err();
    assert!(
        matches!(&err, Kitti360Error::Parse { path: p, line: 2, .. } if *p == stamps),
        "{err}"
    );
    std::fs::remove_file(&stamps).unwrap();
    // A bad number in the calibration names its line too.
    let persp = layout::perspective(&root);
    let text = std::fs::read_to_string(&persp)
        .unwrap()
        .replace("P_rect_01: 3", "P_rect_01: x");
    std::fs::write(&persp, text).unwrap();
    let err = Sequence::open(&root, SEQ).unwrap_err();
    assert!(
        matches!(&err, Kitti360Error::Parse { line: 18, .. }),
        "{err}"
    );
}

#[test]
fn missing_key_is_named() {
    let root = small_sequence("missing-key");
    let persp = layout::perspective(&root);
    let text: String = std::fs::read_to_string(&persp)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with("P_rect_01:"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&persp, text).unwrap();
    let err = Calibration::read(&root).unwrap_err();
    assert!(
        matches!(&err, Kitti360Error::MissingKey { key, .. } if key == "P_rect_01"),
        "{err}"
    );
}

#[test]
fn non_rectified_calibration_is_refused() {
    let mut calib = Calibration::synthetic(W, H);
    calib.p_rect_01[1][2] += 3.0;
    let err = calib.rig().unwrap_err();
    assert!(matches!(err, Kitti360Error::NonRectified { .. }), "{err}");
    let root = temp_root("nonrect");
    assert!(SequenceWriter::create(&root, SEQ, &calib).is_err());
}
