//! The synthetic street generator: determinism, exact depth, stereo and LiDAR consistency,
//! trajectory shape, scene content and image statistics.

use glam::DVec3;
use model::frame::RgbImage;
use model::kitti360::Calibration;
use model::synth::{
    camera_ray, SurfaceClass, SynthConfig, SynthSequence, CAMERA_HEIGHT, KERB_HEIGHT,
};

fn sequence(seed: u64, frames: u32, width: u32, height: u32) -> SynthSequence {
    let config = SynthConfig {
        seed,
        frames,
        width,
        height,
        ..SynthConfig::default()
    };
    let calibration = Calibration::synthetic(width, height);
    SynthSequence::new(config, calibration.rig().unwrap(), calibration.cam_to_velo)
}

fn median(mut v: Vec<f64>) -> f64 {
    assert!(!v.is_empty());
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Bilinear colour at a sub-pixel position (x within the image).
fn bilinear(img: &RgbImage, x: f64, y: u32) -> [f64; 3] {
    let x0 = x.floor() as u32;
    let f = x - x0 as f64;
    let a = img.pixel(x0, y);
    let b = img.pixel((x0 + 1).min(img.width - 1), y);
    [0, 1, 2].map(|c| a[c] as f64 * (1.0 - f) + b[c] as f64 * f)
}

#[test]
fn same_seed_same_bits_other_seed_differs() {
    let a = sequence(7, 5, 136, 36).frame(4);
    let b = sequence(7, 5, 136, 36).frame(4);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.frame.left.data), bits(&b.frame.left.data));
    assert_eq!(bits(&a.frame.right.data), bits(&b.frame.right.data));
    assert_eq!(bits(&a.left_depth.data), bits(&b.left_depth.data));
    let flat = |p: &[[f32; 4]]| p.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(flat(&a.lidar), flat(&b.lidar));
    assert_eq!(a.frame.left_to_world, b.frame.left_to_world);

    // Independent of how rayon schedules rows: one worker thread gives the same bits.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let single = pool.install(|| sequence(7, 5, 136, 36).frame(4));
    assert_eq!(bits(&a.frame.left.data), bits(&single.frame.left.data));
    assert_eq!(flat(&a.lidar), flat(&single.lidar));

    let c = sequence(8, 5, 136, 36).frame(4);
    assert_ne!(a.frame.left.data, c.frame.left.data);
    assert_ne!(a.frame.left_to_world, c.frame.left_to_world);
}

#[test]
fn road_depth_matches_the_analytic_plane() {
    let (w, h) = (272, 72);
    let seq = sequence(1, 30, w, h);
    let k = seq.rig().intrinsics;
    for i in [0usize, 15, 29] {
        let frame = seq.frame(i);
        let pose = seq.pose(i);
        assert!((pose.translation.z - CAMERA_HEIGHT).abs() < 1e-12);
        // The camera looks slightly down: pitch from the optical axis' world z.
        let pitch = (-pose.matrix3.z_axis.z).asin();
        assert!(pitch > 0.4f64.to_radians() && pitch < 2.1f64.to_radians());
        assert!(pose.matrix3.x_axis.z.abs() < 1e-12, "no roll");
        let (u, v) = (w / 2, h - 1);
        let y = (v as f64 - k.cy as f64) / k.fy as f64;
        let expected = CAMERA_HEIGHT / (pitch.sin() + pitch.cos() * y);
        let ray = camera_ray(&pose, &k, u as f64, v as f64);
        assert!((ray.origin.z + ray.dir.z * expected).abs() < 1e-9);
        let got = frame.left_depth.data[(v * w + u) as usize] as f64;
        let rel = (got - expected).abs() / expected;
        assert!(rel < 1e-4, "frame {i}: depth {got} vs plane {expected}");
    }
}

#[test]
fn right_image_matches_left_through_disparity() {
    let (w, h) = (272, 72);
    let seq = sequence(2, 10, w, h);
    let rig = *seq.rig();
    let f = seq.frame(6);
    let mut diffs = Vec::new();
    for v in 0..h {
        for u in 0..w {
            let d = f.left_depth.data[(v * w + u) as usize] as f64;
            if d <= 0.0 {
                continue;
            }
            let ur = u as f64 - rig.intrinsics.fx as f64 * rig.baseline / d;
            if ur < 0.0 || ur > (w - 1) as f64 {
                continue;
            }
            let l = f.frame.left.pixel(u, v);
            let r = bilinear(&f.frame.right, ur, v);
            diffs.push((0..3).map(|c| (l[c] as f64 - r[c]).abs()).sum::<f64>() / 3.0);
        }
    }
    assert!(diffs.len() > (w * h / 2) as usize);
    let med = median(diffs.clone());
    let high = {
        let mut s = diffs.clone();
        s.sort_by(f64::total_cmp);
        s[s.len() * 3 / 4]
    };
    eprintln!("stereo: median {med}, 75th percentile {high}");
    assert!(med < 0.01, "median |left - right| {med}");
    assert!(high < 0.03, "75th percentile |left - right| {high}");
}

#[test]
fn lidar_points_agree_with_camera_depth() {
    let (w, h) = (272, 72);
    let seq = sequence(4, 20, w, h);
    let k = seq.rig().intrinsics;
    let velo_to_cam = Calibration::synthetic(w, h).cam_to_velo.inverse();
    let f = seq.frame(12);
    let pose = seq.pose(12);
    assert!(f.lidar.len() > 30_000, "{} points", f.lidar.len());
    let mut errors = Vec::new();
    let mut road = 0;
    for p in &f.lidar {
        let v = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        assert!(v.length() <= 120.0 + 1e-3);
        assert!((0.0..=1.0).contains(&p[3]));
        let c = velo_to_cam.transform_point3(v);
        // Points on the road lie on the world plane z = 0.
        if pose.transform_point3(c).z.abs() < 1e-4 {
            road += 1;
        }
        if c.z < 1.0 {
            continue;
        }
        // Inverse depth is linear in the image over a plane: interpolate it bilinearly
        // between the four surrounding pixel centres where all four see a surface.
        let u = k.fx as f64 * c.x / c.z + k.cx as f64;
        let vv = k.fy as f64 * c.y / c.z + k.cy as f64;
        if u < 0.0 || vv < 0.0 || u >= (w - 1) as f64 || vv >= (h - 1) as f64 {
            continue;
        }
        let (x0, y0) = (u.floor() as u32, vv.floor() as u32);
        let (fx, fy) = (u - x0 as f64, vv - y0 as f64);
        let at = |x: u32, y: u32| f.left_depth.data[(y * w + x) as usize] as f64;
        let corners = [
            at(x0, y0),
            at(x0 + 1, y0),
            at(x0, y0 + 1),
            at(x0 + 1, y0 + 1),
        ];
        if corners.iter().any(|d| *d <= 0.0) {
            continue;
        }
        let inv = |d: f64| 1.0 / d;
        let top = inv(corners[0]) * (1.0 - fx) + inv(corners[1]) * fx;
        let bottom = inv(corners[2]) * (1.0 - fx) + inv(corners[3]) * fx;
        let d = 1.0 / (top * (1.0 - fy) + bottom * fy);
        errors.push((d - c.z).abs() / c.z);
    }
    assert!(road > 5_000, "{road} road points");
    assert!(errors.len() > 2_000, "{} points in view", errors.len());
    let med = median(errors);
    eprintln!(
        "lidar: {} points, {road} on the road, median relative error {med}",
        f.lidar.len()
    );
    assert!(med < 1e-3, "median relative depth error {med}");
}

#[test]
fn trajectory_moves_smoothly_and_curves() {
    let seq = sequence(5, 300, 136, 36);
    let mut headings = Vec::new();
    let mut spacings = Vec::new();
    for i in 0..seq.len() {
        let pose = seq.pose(i);
        let fwd = pose.matrix3.z_axis;
        headings.push(fwd.y.atan2(fwd.x));
        if i > 0 {
            spacings.push((pose.translation - seq.pose(i - 1).translation).length());
        }
        assert_eq!(seq.timestamp_ns(i), i as i64 * 100_000_000);
    }
    for s in &spacings {
        assert!((0.2..=1.5).contains(s), "frame spacing {s}");
    }
    for pair in spacings.windows(2) {
        assert!((pair[1] - pair[0]).abs() < 0.05, "speed jump {pair:?}");
    }
    let mut unwrapped = vec![headings[0]];
    for pair in headings.windows(2) {
        let mut d = pair[1] - pair[0];
        d = (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        assert!(d.abs() < 1.5f64.to_radians(), "heading step {d}");
        unwrapped.push(unwrapped.last().unwrap() + d);
    }
    let span = unwrapped.iter().cloned().fold(f64::MIN, f64::max)
        - unwrapped.iter().cloned().fold(f64::MAX, f64::min);
    assert!(
        span > 10f64.to_radians(),
        "heading span {} deg",
        span.to_degrees()
    );
    let travelled: f64 = spacings.iter().sum();
    assert!(travelled > 100.0 && travelled < 360.0, "{travelled} m");
}

#[test]
fn every_class_is_seen_in_the_first_hundred_frames() {
    let seq = sequence(0, 100, 272, 72);
    let mut seen = std::collections::BTreeSet::new();
    for i in (0..100).step_by(4) {
        seen.extend(seq.left_classes(i));
    }
    for class in [
        SurfaceClass::Sky,
        SurfaceClass::Road,
        SurfaceClass::Marking,
        SurfaceClass::Sidewalk,
        SurfaceClass::Facade,
        SurfaceClass::Window,
        SurfaceClass::Car,
        SurfaceClass::Pole,
        SurfaceClass::Trunk,
        SurfaceClass::Canopy,
    ] {
        assert!(
            seen.contains(&class),
            "{class:?} never visible; seen {seen:?}"
        );
    }
}

#[test]
fn images_have_contrast_and_no_clipping() {
    for seed in [0, 9] {
        let f = sequence(seed, 3, 272, 72).frame(2);
        for img in [&f.frame.left, &f.frame.right] {
            let luma: Vec<f64> = img
                .data
                .chunks_exact(3)
                .map(|c| (0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]) as f64)
                .collect();
            let mean = luma.iter().sum::<f64>() / luma.len() as f64;
            let std =
                (luma.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / luma.len() as f64).sqrt();
            assert!(std > 0.08, "seed {seed}: luminance std {std}");
            assert!(mean > 0.2 && mean < 0.8, "seed {seed}: mean {mean}");
            let clipped = img
                .data
                .iter()
                .filter(|&&x| !(0.002..=0.998).contains(&x))
                .count();
            assert!(
                clipped * 100 < img.data.len(),
                "seed {seed}: {clipped} clipped values"
            );
        }
        assert!(f.left_depth.valid_count() > f.left_depth.data.len() / 2);
        assert!(f.left_depth.data.iter().all(|d| (0.0..=1000.0).contains(d)));
    }
}

#[test]
fn ground_classes_lie_on_their_planes() {
    let (w, h) = (272, 72);
    let seq = sequence(6, 20, w, h);
    let k = seq.rig().intrinsics;
    let i = 10;
    let (frame, classes, pose) = (seq.frame(i), seq.left_classes(i), seq.pose(i));
    let (mut road, mut raised) = (0, 0);
    for v in 0..h {
        for u in 0..w {
            let idx = (v * w + u) as usize;
            let d = frame.left_depth.data[idx] as f64;
            let ray = camera_ray(&pose, &k, u as f64, v as f64);
            let z = ray.origin.z + ray.dir.z * d;
            match classes[idx] {
                SurfaceClass::Road | SurfaceClass::Marking => {
                    assert!(z.abs() < 1e-3, "road at z {z}");
                    road += 1;
                }
                SurfaceClass::Sidewalk | SurfaceClass::Verge => {
                    assert!((z - KERB_HEIGHT).abs() < 1e-3, "sidewalk at z {z}");
                    raised += 1;
                }
                SurfaceClass::Sky => assert_eq!(d, 0.0),
                _ => assert!(d > 0.0),
            }
        }
    }
    assert!(
        road > 1000 && raised > 100,
        "{road} road, {raised} sidewalk pixels"
    );
}
