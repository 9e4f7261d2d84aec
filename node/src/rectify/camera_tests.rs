//! The checks of a `CameraInfo` and of a stereo pair: every refusal names its field and
//! value; binning, pass-through and rebuild-on-change.

use super::*;
use crate::rectify::test_support::{cameras, info, k_matrix, p_matrix, rotation, IDENTITY};
use crate::rectify::RemapError;
use crate::rectify::{Rectifier, StereoError, StereoRig};

/// The VGA plumb_bob camera (left) every check starts from.
fn vga() -> CameraInfo {
    info(
        (640, 480),
        "plumb_bob",
        &[-0.28, 0.07, 0.0005, -0.0003, 0.0],
        k_matrix(500.0, 500.0, 320.0, 240.0),
        rotation([0.0, 1.0, 0.0], 1.0),
        p_matrix(480.0, 480.0, 322.0, 241.0, 0.0),
    )
}

fn err(info: &CameraInfo) -> CalibrationError {
    CameraModel::from_camera_info(info).expect_err("refused")
}

#[test]
fn each_model_reads_its_coefficients() {
    for (name, info) in cameras() {
        let m = CameraModel::from_camera_info(&info).expect(name);
        assert_eq!(m.distortion().coefficients(), &info.d[..], "{name}");
        assert_eq!((m.width(), m.height()), (info.width, info.height));
        assert!(!m.is_rectified(), "{name}");
    }
    let mut four = vga();
    four.d.truncate(4);
    let m = CameraModel::from_camera_info(&four).unwrap();
    assert_eq!(
        m.distortion(),
        Distortion::PlumbBob([-0.28, 0.07, 0.0005, -0.0003, 0.0])
    );
    for model in [
        "plumb_bob",
        "rational_polynomial",
        "equidistant",
        "",
        "anything",
    ] {
        let mut empty = vga();
        empty.distortion_model = model.into();
        empty.d.clear();
        let m = CameraModel::from_camera_info(&empty).unwrap();
        assert_eq!(m.distortion(), Distortion::None, "{model:?}");
    }
    let mut unnamed = vga();
    unnamed.distortion_model.clear();
    unnamed.d = vec![0.0; 5];
    assert_eq!(
        CameraModel::from_camera_info(&unnamed)
            .unwrap()
            .distortion(),
        Distortion::None
    );
}

#[test]
fn wrong_coefficient_counts_and_unknown_models_are_refused() {
    for (model, n) in [
        ("plumb_bob", 8),
        ("plumb_bob", 3),
        ("plumb_bob", 14),
        ("rational_polynomial", 5),
        ("equidistant", 5),
    ] {
        let mut i = vga();
        i.distortion_model = model.into();
        i.d = vec![0.01; n];
        match err(&i) {
            CalibrationError::CoefficientCount {
                model: m, count, ..
            } => {
                assert_eq!((m.as_str(), count), (model, n));
            }
            other => panic!("{model} {n}: {other}"),
        }
    }
    let mut i = vga();
    i.distortion_model = "fov".into();
    let e = err(&i);
    assert_eq!(
        e,
        CalibrationError::UnknownModel {
            model: "fov".into()
        }
    );
    assert!(e.to_string().contains("\"fov\""), "{e}");
    i.distortion_model.clear();
    assert!(matches!(err(&i), CalibrationError::UnknownModel { .. }));
}

#[test]
fn non_finite_numbers_are_named_by_field_and_index() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut i = vga();
        i.d[2] = bad;
        assert!(matches!(
            err(&i),
            CalibrationError::NonFinite {
                field: "d",
                index: 2,
                ..
            }
        ));
        let mut i = vga();
        i.k[4] = bad;
        assert!(matches!(
            err(&i),
            CalibrationError::NonFinite {
                field: "k",
                index: 4,
                ..
            }
        ));
        let mut i = vga();
        i.r[7] = bad;
        assert!(matches!(
            err(&i),
            CalibrationError::NonFinite {
                field: "r",
                index: 7,
                ..
            }
        ));
        let mut i = vga();
        i.p[3] = bad;
        let e = err(&i);
        assert!(matches!(
            e,
            CalibrationError::NonFinite {
                field: "p",
                index: 3,
                ..
            }
        ));
        assert!(e.to_string().contains("camera_info.p[3]"), "{e}");
    }
}

#[test]
fn k_and_p_must_have_their_form_and_positive_focal_lengths() {
    let mut i = vga();
    i.k[0] = 0.0;
    assert_eq!(
        err(&i),
        CalibrationError::Focal {
            field: "k",
            fx: 0.0,
            fy: 500.0
        }
    );
    let mut i = vga();
    i.p[5] = -480.0;
    assert!(matches!(
        err(&i),
        CalibrationError::Focal { field: "p", .. }
    ));
    let mut i = vga();
    i.k[1] = 0.5; // skew
    assert!(matches!(
        err(&i),
        CalibrationError::Form {
            field: "k",
            index: 1,
            ..
        }
    ));
    let mut i = vga();
    i.k[8] = 2.0;
    assert!(matches!(
        err(&i),
        CalibrationError::Form {
            field: "k",
            index: 8,
            ..
        }
    ));
    for index in [1, 4, 8, 9, 10, 11] {
        let mut i = vga();
        i.p[index] += 0.25;
        match err(&i) {
            CalibrationError::Form {
                field: "p",
                index: at,
                ..
            } => assert_eq!(at, index),
            other => panic!("p[{index}]: {other}"),
        }
    }
}

#[test]
fn r_must_be_a_rotation() {
    let mut i = vga();
    i.r = [1.01, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    assert!(matches!(err(&i), CalibrationError::NotRotation { .. }));
    // A reflection is orthonormal with det -1.
    i.r = [-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    match err(&i) {
        CalibrationError::NotRotation { det, .. } => assert_eq!(det, -1.0),
        other => panic!("{other}"),
    }
    i.r = [0.0; 9];
    assert!(matches!(err(&i), CalibrationError::NotRotation { .. }));
    // Printed with 6 decimals, a rotation is still one.
    i.r = rotation([1.0, 2.0, 3.0], 2.0).map(|v| (v * 1e6).round() / 1e6);
    CameraModel::from_camera_info(&i).unwrap();
}

#[test]
fn sizes_binning_and_roi() {
    for (w, h) in [(0, 480), (640, 0), (MAX_SIDE + 1, 2), (10_000, 10_000)] {
        let mut i = vga();
        (i.width, i.height) = (w, h);
        assert!(matches!(err(&i), CalibrationError::Size { .. }), "{w}x{h}");
    }
    let mut i = vga();
    (i.binning_x, i.binning_y) = (2, 4);
    let m = CameraModel::from_camera_info(&i).unwrap();
    assert_eq!((m.width(), m.height()), (320, 120));
    assert_eq!(
        m.k(),
        Pinhole {
            fx: 250.0,
            fy: 125.0,
            cx: 160.0,
            cy: 60.0
        }
    );
    assert_eq!((m.p().fx, m.p().cy), (240.0, 241.0 / 4.0));
    i.binning_x = 1000;
    assert!(matches!(err(&i), CalibrationError::Binning { x: 1000, .. }));
    let mut i = vga();
    i.roi.width = 640;
    i.roi.height = 480;
    CameraModel::from_camera_info(&i).unwrap();
    i.roi.x_offset = 10;
    let e = err(&i);
    assert!(matches!(e, CalibrationError::Roi { .. }));
    assert!(e.to_string().contains("not supported"), "{e}");
}

#[test]
fn pass_through_needs_zero_d_identity_r_and_p_equal_to_k() {
    let k = k_matrix(500.0, 500.0, 320.0, 240.0);
    let p = p_matrix(500.0, 500.0, 320.0, 240.0, -60.0);
    let rectified = info((640, 480), "plumb_bob", &[0.0; 5], k, IDENTITY, p);
    let m = CameraModel::from_camera_info(&rectified).unwrap();
    assert!(m.is_rectified());
    let rectifier = Rectifier::new(m);
    assert!(rectifier.table().is_none());
    let image = crate::rectify::test_support::textured(640, 480);
    let out = rectifier.rectify(&image).unwrap();
    assert!(matches!(out, std::borrow::Cow::Borrowed(_)));
    assert_eq!(*out, image);
    let small = crate::rectify::test_support::textured(64, 48);
    assert!(matches!(
        rectifier.rectify(&small),
        Err(RemapError::Size { .. })
    ));

    let mut moved = rectified.clone();
    moved.p[2] += 0.5;
    let mut turned = rectified.clone();
    turned.r = rotation([0.0, 1.0, 0.0], 0.5);
    let mut distorted = rectified.clone();
    distorted.d[0] = -0.1;
    for other in [moved, turned, distorted] {
        let m = CameraModel::from_camera_info(&other).unwrap();
        assert!(!m.is_rectified());
        assert!(Rectifier::new(m).table().is_some());
    }
}

#[test]
fn the_table_is_rebuilt_only_when_the_calibration_changes() {
    let mut rectifier = Rectifier::new(CameraModel::from_camera_info(&vga()).unwrap());
    let mut same = vga();
    same.header.stamp.sec = 99;
    assert!(!rectifier.update(CameraModel::from_camera_info(&same).unwrap()));
    let mut changed = vga();
    changed.d[0] = -0.27;
    assert!(rectifier.update(CameraModel::from_camera_info(&changed).unwrap()));
    assert_eq!(rectifier.camera().distortion().coefficients()[0], -0.27);
}

/// The VGA camera as a stereo pair with a 0.12 m baseline.
fn pair() -> (CameraInfo, CameraInfo) {
    let left = vga();
    let mut right = vga();
    right.r = rotation([0.0, 1.0, 0.0], -1.0);
    right.p[3] = -480.0 * 0.12;
    (left, right)
}

#[test]
fn a_stereo_pair_shares_p_and_has_a_horizontal_baseline() {
    let (l, r) = pair();
    let rig = StereoRig::from_camera_infos(&l, &r).unwrap();
    assert!((rig.baseline() - 0.12).abs() < 1e-12);
    let (k, baseline) = rig.intrinsics();
    assert_eq!(
        (k.fx, k.cx, k.cy, k.width, k.height),
        (480.0, 322.0, 241.0, 640, 480)
    );
    assert_eq!(baseline, rig.baseline());
    let (mut l2, mut r2) = pair();
    for i in [&mut l2, &mut r2] {
        (i.binning_x, i.binning_y) = (2, 2);
    }
    let binned = StereoRig::from_camera_infos(&l2, &r2).unwrap();
    let (k, b) = binned.intrinsics();
    assert_eq!((k.fx, k.cx, k.width, k.height), (240.0, 161.0, 320, 240));
    assert!((b - 0.12).abs() < 1e-12, "{b}");
    let mut rectifier = crate::rectify::StereoRectifier::new(rig.clone());
    assert!(!rectifier.update(rig));

    for (index, what) in [(0, "fx'"), (5, "fy'"), (2, "cx'"), (6, "cy'")] {
        let (l, mut r) = pair();
        r.p[index] += 0.5;
        let e = StereoRig::from_camera_infos(&l, &r).unwrap_err();
        assert!(
            matches!(e, StereoError::Projection { what: w, .. } if w == what),
            "{e}"
        );
        assert!(e
            .to_string()
            .contains("no rectified rig can come from these"));
    }
    let (l, mut r) = pair();
    r.p[7] = 3.0;
    let e = StereoRig::from_camera_infos(&l, &r).unwrap_err();
    assert!(
        matches!(e, StereoError::Baseline { side: "right", .. }),
        "{e}"
    );
    let (l, mut r) = pair();
    r.p[3] = 57.6;
    assert!(matches!(
        StereoRig::from_camera_infos(&l, &r),
        Err(StereoError::Baseline { side: "right", .. })
    ));
    let (mut l, r) = pair();
    l.p[3] = -10.0;
    assert!(matches!(
        StereoRig::from_camera_infos(&l, &r),
        Err(StereoError::Baseline { side: "left", .. })
    ));
    let (l, mut r) = pair();
    r.width = 320;
    r.roi = Default::default();
    assert!(matches!(
        StereoRig::from_camera_infos(&l, &r),
        Err(StereoError::Size { .. })
    ));
    let (l, mut r) = pair();
    r.k[0] = f64::NAN;
    let e = StereoRig::from_camera_infos(&l, &r).unwrap_err();
    assert!(matches!(
        e,
        StereoError::Right(CalibrationError::NonFinite { .. })
    ));
    assert!(std::error::Error::source(&e).is_some());
}
