//! The tables against the models: distort then rectify returns the image, the coordinates
//! match an independent evaluation of each model, and the extremes (huge coefficients,
//! rays at and past 90 degrees, 1x1 images) stay finite or black without a panic.

use glam::{DMat3, DVec2, DVec3};

use super::*;
use crate::msg::sensor_msgs::CameraInfo;
use crate::rectify::test_support::{
    cameras, compare, info, k_matrix, p_matrix, rotation, textured, IDENTITY,
};
use crate::rectify::Distortion;

fn model(info: &CameraInfo) -> CameraModel {
    CameraModel::from_camera_info(info).expect("a valid calibration")
}

fn white(width: u32, height: u32) -> Rgb8Image {
    Rgb8Image {
        width,
        height,
        data: vec![255; 3 * width as usize * height as usize],
    }
}

#[test]
fn distort_then_rectify_returns_the_image_for_each_model() {
    // (model, PSNR floor dB, largest error allowed): measured 50.6 / 50.4 / 48.1 dB, max
    // 3 / 4 / 6 levels (two bilinear resamplings of the texture).
    for ((name, info), (min_psnr, max_err)) in
        cameras()
            .into_iter()
            .zip([(48.0, 6), (48.0, 7), (46.0, 10)])
    {
        let m = model(&info);
        let (w, h) = (m.width(), m.height());
        let original = textured(w, h);
        let raw = RemapTable::distort(&m).remap(&original).unwrap();
        let rectify = RemapTable::rectify(&m);
        let back = rectify.remap(&raw).unwrap();
        // Away from the borders: 4 px inside the rectified image, sampling 2 px inside raw.
        let keep = |x: u32, y: u32| {
            let [rx, ry] = rectify.coordinates()[(y * w + x) as usize];
            x >= 4
                && y >= 4
                && x + 4 < w
                && y + 4 < h
                && rx >= 2.0
                && ry >= 2.0
                && rx <= (w - 3) as f32
                && ry <= (h - 3) as f32
        };
        let (psnr, max, n) = compare(&original, &back, keep);
        eprintln!("{name}: {psnr:.1} dB, max {max}, {n} of {} pixels", w * h);
        assert!(
            n as f64 > 0.5 * (w * h) as f64,
            "{name}: {n} pixels compared"
        );
        assert!(psnr >= min_psnr, "{name}: {psnr:.2} dB");
        assert!(max <= max_err, "{name}: max error {max}");
    }
}

/// The raw pixel of rectified pixel `px`, evaluated from the formulas as written (R's
/// transpose for its inverse, the polynomials in powers), not through the module's code.
fn independent(info: &CameraInfo, px: DVec2) -> DVec2 {
    let (k, p, d) = (&info.k, &info.p, &info.d);
    let r = DMat3::from_cols_array(&info.r); // column major of row-major R: Rᵀ
    let ray = r * DVec3::new((px.x - p[2]) / p[0], (px.y - p[6]) / p[5], 1.0);
    let (x, y) = (ray.x / ray.z, ray.y / ray.z);
    let (xd, yd) = if info.distortion_model == "equidistant" {
        let rr = (x * x + y * y).sqrt();
        let t = rr.atan();
        let td = t + d[0] * t.powi(3) + d[1] * t.powi(5) + d[2] * t.powi(7) + d[3] * t.powi(9);
        (x * td / rr, y * td / rr)
    } else {
        let c = |i: usize| d.get(i).copied().unwrap_or(0.0);
        let r2 = x * x + y * y;
        let radial = (1.0 + c(0) * r2 + c(1) * r2.powi(2) + c(4) * r2.powi(3))
            / (1.0 + c(5) * r2 + c(6) * r2.powi(2) + c(7) * r2.powi(3));
        (
            x * radial + 2.0 * c(2) * x * y + c(3) * (r2 + 2.0 * x * x),
            y * radial + c(2) * (r2 + 2.0 * y * y) + 2.0 * c(3) * x * y,
        )
    };
    DVec2::new(k[0] * xd + k[2], k[4] * yd + k[5])
}

#[test]
fn table_coordinates_match_an_independent_evaluation() {
    for (name, info) in cameras() {
        let m = model(&info);
        let table = RemapTable::rectify(&m);
        let (mut worst, mut n) = (0.0f64, 0);
        for y in (0..m.height()).step_by(23) {
            for x in (0..m.width()).step_by(37) {
                let want = independent(&info, DVec2::new(x as f64, y as f64));
                let [gx, gy] = table.coordinates()[(y * m.width() + x) as usize];
                worst = worst.max(
                    (want - DVec2::new(gx as f64, gy as f64))
                        .abs()
                        .max_element(),
                );
                n += 1;
            }
        }
        eprintln!("{name}: {n} points, worst {worst:.2e} px");
        // f32 coordinates near 1400 px are good to 6e-5 px.
        assert!(worst < 2e-4, "{name}: {worst} px");
    }
}

#[test]
fn the_distortion_table_inverts_the_rectification() {
    for (name, info) in cameras() {
        let m = model(&info);
        let ray_from_rectified = m.ray_from_rectified();
        let mut worst = 0.0f64;
        for y in (0..m.height()).step_by(17) {
            for x in (0..m.width()).step_by(19) {
                let raw = DVec2::new(x as f64, y as f64);
                let rectified = m.rectified_of_raw(raw).expect("every raw pixel is seen");
                let again = m.raw_of_rectified(&ray_from_rectified, rectified).unwrap();
                worst = worst.max((again - raw).length());
            }
        }
        assert!(worst < 1e-7, "{name}: {worst} px");
    }
}

#[test]
fn an_undistorted_camera_gives_the_identity_table_and_an_exact_copy() {
    let k = k_matrix(400.0, 410.0, 160.5, 119.5);
    let p = p_matrix(400.0, 410.0, 160.5, 119.5, 0.0);
    let m = model(&info((321, 239), "plumb_bob", &[0.0; 5], k, IDENTITY, p));
    let table = RemapTable::rectify(&m);
    for (i, [x, y]) in table.coordinates().iter().enumerate() {
        let (px, py) = ((i % 321) as f32, (i / 321) as f32);
        assert!(
            (x - px).abs() < 1e-4 && (y - py).abs() < 1e-4,
            "{i}: {x} {y}"
        );
    }
    let image = textured(321, 239);
    assert_eq!(table.remap(&image).unwrap(), image);
}

#[test]
fn pixels_off_the_raw_image_are_black() {
    // A rectified view wider than the raw one: its corners see no raw pixel.
    let k = k_matrix(500.0, 500.0, 320.0, 240.0);
    let p = p_matrix(200.0, 200.0, 320.0, 240.0, 0.0);
    let m = model(&info(
        (640, 480),
        "plumb_bob",
        &[-0.05, 0.0, 0.0, 0.0, 0.0],
        k,
        IDENTITY,
        p,
    ));
    let table = RemapTable::rectify(&m);
    let out = table.remap(&white(640, 480)).unwrap();
    let [cx, _] = table.coordinates()[0];
    assert!(cx < -1.0, "corner samples raw x {cx}");
    assert_eq!(&out.data[..3], &[0, 0, 0]);
    let centre = 3 * (240 * 640 + 320);
    assert_eq!(&out.data[centre..centre + 3], &[255, 255, 255]);
    // The raw image covers 0.4 x 0.4 of the rectified one, a little more through the barrel
    // distortion (256 x 192 = 49152 pixels without it).
    let lit = out.data.chunks(3).filter(|p| p != &[0, 0, 0]).count();
    assert!((49_152..54_000).contains(&lit), "{lit} pixels not black");
}

#[test]
fn huge_coefficients_give_finite_coordinates_or_black_pixels() {
    let r = rotation([1.0, 1.0, 0.0], 2.0);
    let k = k_matrix(60.0, 60.0, 32.0, 24.0);
    let p = p_matrix(55.0, 55.0, 32.0, 24.0, 0.0);
    let cases: [(&str, Vec<f64>); 6] = [
        ("plumb_bob", vec![1e30, -1e30, 1e20, 1e20, 1e300]),
        ("plumb_bob", vec![-1e300, 1e300, -1e300, 1e300, -1e300]),
        (
            "rational_polynomial",
            vec![1e300, 1e300, 0.0, 0.0, 1e300, -1e300, 1e300, -1e300],
        ),
        (
            "rational_polynomial",
            vec![0.0, 0.0, 0.0, 0.0, 0.0, -1e6, 0.0, 0.0],
        ),
        ("equidistant", vec![1e300, -1e300, 1e300, -1e300]),
        ("equidistant", vec![-50.0, 0.0, 0.0, 0.0]),
    ];
    for (name, d) in cases {
        let m = model(&info((64, 48), name, &d, k, r, p));
        for table in [RemapTable::rectify(&m), RemapTable::distort(&m)] {
            let out = table.remap(&white(64, 48)).unwrap();
            for (c, px) in table.coordinates().iter().zip(out.data.chunks(3)) {
                let finite = c[0].is_finite() && c[1].is_finite();
                assert!(finite || px == [0, 0, 0], "{name} {d:?}: {c:?} gave {px:?}");
            }
        }
    }
}

#[test]
fn a_one_pixel_image_goes_through_both_ways() {
    let k = k_matrix(1.0, 1.0, 0.0, 0.0);
    let m = model(&info(
        (1, 1),
        "plumb_bob",
        &[-0.3, 0.1, 0.0, 0.0, 0.0],
        k,
        IDENTITY,
        p_matrix(1.0, 1.0, 0.0, 0.0, 0.0),
    ));
    let image = Rgb8Image {
        width: 1,
        height: 1,
        data: vec![10, 20, 30],
    };
    for table in [RemapTable::rectify(&m), RemapTable::distort(&m)] {
        assert_eq!(table.coordinates(), &[[0.0, 0.0]]);
        assert_eq!(table.remap(&image).unwrap(), image);
    }
}

#[test]
fn equidistant_rays_at_and_past_ninety_degrees() {
    let fisheye = Distortion::Equidistant([0.0; 4]);
    let side = std::f64::consts::FRAC_PI_2;
    for degrees in [90.0f64, 100.0, 170.0] {
        let t = degrees.to_radians();
        let ray = DVec3::new(t.sin(), 0.0, t.cos());
        let d = fisheye.distort_ray(ray).unwrap();
        assert!((d.x - t).abs() < 1e-12 && d.y == 0.0, "{degrees}: {d}");
        let back = fisheye.undistort(d).unwrap().normalize();
        assert!((back - ray).length() < 1e-9, "{degrees}: {back}");
    }
    assert!(fisheye.distort_ray(-DVec3::Z).is_none());
    assert!(Distortion::PlumbBob([0.0; 5])
        .distort_ray(DVec3::new(1.0, 0.0, -0.1))
        .is_none());
    // A fisheye of 200 px focal length on 640x480 sees 115 degrees off axis at its corners:
    // those raw pixels have no rectified pixel and come out black.
    let k = k_matrix(200.0, 200.0, 320.0, 240.0);
    let p = p_matrix(200.0, 200.0, 320.0, 240.0, 0.0);
    let m = model(&info((640, 480), "equidistant", &[0.0; 4], k, IDENTITY, p));
    let table = RemapTable::distort(&m);
    let out = table.remap(&white(640, 480)).unwrap();
    assert!(table.coordinates()[0][0].is_nan());
    assert_eq!(&out.data[..3], &[0, 0, 0]);
    let beyond = |x: f64, y: f64| ((x - 320.0).hypot(y - 240.0) / 200.0) >= side;
    for (i, c) in table.coordinates().iter().enumerate() {
        let (x, y) = ((i % 640) as f64, (i / 640) as f64);
        assert_eq!(c[0].is_nan(), beyond(x, y), "raw ({x}, {y}): {c:?}");
    }
    // Turned 120 degrees, the rectified centre looks behind the fisheye yet onto its image.
    let turned = model(&info(
        (640, 480),
        "equidistant",
        &[0.0; 4],
        k,
        rotation([0.0, 1.0, 0.0], 120.0),
        p,
    ));
    let at = turned
        .raw_of_rectified(&turned.ray_from_rectified(), DVec2::new(320.0, 240.0))
        .unwrap();
    assert!(
        ((at.x - 320.0).abs() - 200.0 * 120f64.to_radians()).abs() < 1e-9,
        "{at}"
    );
}

#[test]
fn a_folding_lens_has_no_inverse_past_its_fold() {
    // r_d = r (1 - r²) peaks at 0.385 for r = 0.577.
    let lens = Distortion::PlumbBob([-1.0, 0.0, 0.0, 0.0, 0.0]);
    assert!(lens.undistort(DVec2::new(0.5, 0.0)).is_none());
    let p = lens.undistort(DVec2::new(0.3, 0.0)).unwrap();
    assert!(
        (p.x * (1.0 - p.x * p.x) - 0.3).abs() < 1e-12 && p.x < 0.577,
        "{p}"
    );
    assert!(lens.undistort(DVec2::new(f64::NAN, 0.0)).is_none());
}

#[test]
fn images_of_another_size_or_length_are_refused() {
    let m = model(&cameras()[1].1);
    let table = RemapTable::rectify(&m);
    assert!(matches!(
        table.remap(&white(320, 240)),
        Err(RemapError::Size { width: 320, .. })
    ));
    let mut short = white(640, 480);
    short.data.pop();
    assert!(matches!(table.remap(&short), Err(RemapError::Data { .. })));
}

#[test]
fn the_sampler_floors_and_rounds_as_the_standard_library() {
    let values = [
        -0.999_999_9f32,
        -0.5,
        -1e-30,
        0.0,
        1e-30,
        0.5,
        1.5,
        2.5,
        2.999_999_8,
        254.5,
        255.49,
        16383.999,
    ];
    for v in values {
        assert_eq!(super::floor(v), v.floor() as i32, "floor {v}");
        assert_eq!(super::round_ties_even(v), v.round_ties_even(), "round {v}");
    }
}
