//! Which voxels the volume branch decodes: the occupancy head against the voxel feature it
//! stands for (and its gradients against finite differences), the frustum mask (in front, inside the image; bin frame, so drives 1e5 m from
//! the world origin change nothing), the top-k selection against brute force (mask, k, ties,
//! NaN), the occupancy target from known points and from a written sequence's LiDAR, and the
//! balanced BCE against its formula and finite differences.

use crate::volume_support;

use std::path::PathBuf;

use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{VarBuilder, VarMap};
use glam::{DAffine3, DQuat, DVec3, Quat, Vec3};
use model::bins::Bin;
use model::frame::{RgbImage, Side, StereoFrame, StereoRig};
use model::kitti360::{Calibration, Sequence, SequenceWriter};
use model::net::volume::voxels::{plane_cell, voxel_at, voxel_count, voxel_index};
use model::net::volume::{
    bin_lidar_points, frustum_mask, occupancy_loss, occupied_voxels, top_k, OccupancyHead, Plane,
    VolumeConfig,
};
use rand::Rng;
use renderer::{Camera, Intrinsics};
use volume_support::{check_gradients, rng, tiny_volume, uniform, values};

/// x -4..4, y -2..2, z -2..8 in 1 m cells.
fn street() -> VolumeConfig {
    VolumeConfig {
        range_min: [-4.0, -2.0, -2.0],
        range_max: [4.0, 2.0, 8.0],
        cells: [8, 4, 10],
        channels: 4,
        top_k: 20,
        ..VolumeConfig::tiny()
    }
}

/// 64 x 32 pixels, 90 degrees across (fx = fy = 32).
fn intrinsics() -> Intrinsics {
    Intrinsics::from_hfov(64, 32, 90.0)
}

#[test]
fn occupancy_is_the_linear_score_of_the_voxel_feature() {
    let cfg = tiny_volume();
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F64, &Device::Cpu);
    let head = OccupancyHead::new(vb.pp("occ"), &cfg).unwrap();
    let mut r = rng(1);
    let planes: [Tensor; 3] = cfg
        .plane_shapes()
        .map(|(rows, cols)| uniform(&mut r, &[cfg.channels, rows, cols], -1.0, 1.0));
    let logits = head.forward(&planes).unwrap();
    assert_eq!(logits.dims(), cfg.cells);
    let data = varmap.data().lock().unwrap();
    let w = values(data["occ.score.weight"].as_tensor());
    let b = values(data["occ.score.bias"].as_tensor())[0];
    let p: Vec<Vec<f64>> = planes.iter().map(values).collect();
    let got = values(&logits);
    assert_eq!(got.len(), voxel_count(&cfg));
    for (flat, got) in got.into_iter().enumerate() {
        let index = voxel_at(&cfg, flat);
        assert_eq!(voxel_index(&cfg, index), flat);
        let mut want = b;
        for (k, plane) in Plane::ALL.into_iter().enumerate() {
            let (rows, cols) = cfg.plane_shapes()[k];
            let cell = plane_cell(&cfg, plane, index);
            want += (0..cfg.channels)
                .map(|c| w[c] * p[k][c * rows * cols + cell])
                .sum::<f64>();
        }
        assert!((got - want).abs() < 1e-12, "voxel {index:?}");
    }
    // Wrong plane shapes are an error.
    let wrong = [planes[1].clone(), planes[1].clone(), planes[2].clone()];
    assert!(head.forward(&wrong).is_err());

    // Gradients with respect to the planes and the head's weights.
    let weight = data["occ.score.weight"].clone();
    let bias = data["occ.score.bias"].clone();
    drop(data);
    let vars = planes.map(|t| Var::from_tensor(&t).unwrap());
    let probe = uniform(&mut r, &cfg.cells, -1.0, 1.0);
    let loss = || {
        let planes = [0, 1, 2].map(|i| vars[i].as_tensor().clone());
        (head.forward(&planes).unwrap() * &probe)
            .unwrap()
            .sum_all()
            .unwrap()
    };
    let worst = check_gradients(
        &[
            ("xz", &vars[0]),
            ("xy", &vars[1]),
            ("zy", &vars[2]),
            ("weight", &weight),
            ("bias", &bias),
        ],
        32,
        &loss,
    );
    assert!(worst < 1e-6, "{worst}");
}

#[test]
fn the_frustum_mask_keeps_voxels_in_front_and_inside_the_image() {
    let cfg = street();
    let camera = Camera::identity(intrinsics());
    let mask = frustum_mask(&cfg, &[camera]);
    let at = |p: [f32; 3]| mask[voxel_index(&cfg, cfg.cell_of(p).unwrap())];
    assert!(at([0.1, 0.1, 5.2])); // straight ahead
    assert!(at([3.2, 1.2, 7.2])); // centre (3.5, 1.5, 7.5): u 46.4, v 21.9
    assert!(!at([0.1, 0.1, -1.5])); // behind
    assert!(!at([3.2, 0.1, 0.2])); // centre (3.5, 0.5, 0.5): u = 255.5, outside
    assert!(!at([0.1, 1.9, 1.2])); // centre (0.5, 1.5, 1.5): v = 47.5, outside
                                   // Every masked voxel's centre projects inside the image, in front.
    for (flat, &seen) in mask.iter().enumerate() {
        let c = cfg.cell_centre(voxel_at(&cfg, flat));
        let (u, v) = (32.0 * c[0] / c[2] + 31.5, 32.0 * c[1] / c[2] + 15.5);
        let inside = c[2] > 0.0 && (-0.5..63.5).contains(&u) && (-0.5..31.5).contains(&v);
        assert_eq!(seen, inside, "voxel centre {c:?}");
    }
    // Two cameras: the union; none: nothing.
    let turned = Camera::from_camera_to_world(
        intrinsics(),
        Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
        Vec3::ZERO,
    );
    let right = frustum_mask(&cfg, &[turned]);
    let both = frustum_mask(&cfg, &[camera, turned]);
    for i in 0..mask.len() {
        assert_eq!(both[i], mask[i] || right[i]);
    }
    assert!(right.iter().any(|&s| s));
    assert!(frustum_mask(&cfg, &[]).iter().all(|&s| !s));
    // Degenerate cameras see nothing: an empty image, NaN optics, a NaN pose.
    let empty = Intrinsics {
        width: 0,
        height: 0,
        ..intrinsics()
    };
    let nan = Intrinsics {
        fx: f32::NAN,
        ..intrinsics()
    };
    let lost = Camera::from_camera_to_world(intrinsics(), Quat::IDENTITY, Vec3::NAN);
    for bad in [Camera::identity(empty), Camera::identity(nan), lost] {
        assert!(frustum_mask(&cfg, &[bad]).iter().all(|&s| !s));
    }
}

#[test]
fn the_mask_is_the_same_for_a_drive_1e5_m_from_the_origin() {
    let cfg = street();
    let rig = StereoRig {
        intrinsics: intrinsics(),
        baseline: 0.54,
    };
    let rotation = DQuat::from_rotation_y(0.7) * DQuat::from_rotation_x(0.05);
    let near = DAffine3::from_rotation_translation(rotation, DVec3::new(3.0, 1.0, -2.0));
    let far = DAffine3::from_rotation_translation(rotation, DVec3::new(1.0e5, -3.0, -1.0e5));
    let cams = |origin: DAffine3| -> Vec<Camera> {
        let next = origin * DAffine3::from_translation(DVec3::new(0.1, 0.0, 1.3));
        [Side::Left, Side::Right]
            .into_iter()
            .flat_map(|s| {
                [
                    rig.local_camera(origin, origin, s),
                    rig.local_camera(origin, next, s),
                ]
            })
            .collect()
    };
    let a = frustum_mask(&cfg, &cams(near));
    let b = frustum_mask(&cfg, &cams(far));
    assert_eq!(a, b);
    assert!(a.iter().filter(|&&s| s).count() > 50);
    // Cameras that are themselves 1e5 m away in the bin frame see no voxel.
    let lost = Camera::from_camera_to_world(intrinsics(), Quat::IDENTITY, Vec3::splat(1.0e5));
    assert!(frustum_mask(&cfg, &[lost]).iter().all(|&s| !s));
}

#[test]
fn top_k_is_the_best_k_allowed_voxels_with_ties_to_the_lower_index() {
    let mut r = rng(3);
    let n = 500;
    // Few distinct values, so many ties; some NaN and infinities.
    let scores: Vec<f32> = (0..n)
        .map(|i| match i % 97 {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => f32::NEG_INFINITY,
            _ => r.random_range(0..12) as f32 * 0.5 - 3.0,
        })
        .collect();
    let mask: Vec<bool> = (0..n).map(|_| r.random_bool(0.6)).collect();
    let logits = Tensor::from_vec(scores.clone(), (5, 10, 10), &Device::Cpu).unwrap();
    for k in [0, 1, 7, 100, 301, 1000] {
        let got = top_k(&logits, &mask, k).unwrap();
        let mut want: Vec<usize> = (0..n).filter(|&i| mask[i] && !scores[i].is_nan()).collect();
        want.sort_by(|&a, &b| scores[b].partial_cmp(&scores[a]).unwrap().then(a.cmp(&b)));
        want.truncate(k);
        want.sort_unstable();
        assert_eq!(got, want, "k = {k}");
        assert!(got.len() <= k && got.iter().all(|&i| mask[i]));
        assert_eq!(top_k(&logits, &mask, k).unwrap(), got, "deterministic");
    }
    assert!(top_k(&logits, &mask[1..], 3).is_err());
}

#[test]
fn hits_mark_exactly_the_voxels_they_fall_in() {
    let cfg = street();
    let points = [
        [0.1, 0.1, 5.2],
        [0.9, 0.9, 5.9],    // same voxel
        [-4.0, -2.0, -2.0], // the near corner: voxel (0, 0, 0)
        [3.99, 1.99, 7.99], // the far corner's voxel
        [4.0, 0.0, 0.0],    // on the far x face: outside
        [f32::NAN, 0.0, 0.0],
        [0.0, 0.0, f32::INFINITY],
        [1e30, 1e30, 1e30],
    ];
    let occupied = occupied_voxels(&cfg, &points);
    let on: Vec<usize> = (0..occupied.len()).filter(|&i| occupied[i]).collect();
    let want = vec![
        voxel_index(&cfg, [0, 0, 0]),
        voxel_index(&cfg, [4, 2, 7]),
        voxel_index(&cfg, [7, 3, 9]),
    ];
    let mut want = want;
    want.sort_unstable();
    assert_eq!(on, want);
}

/// The balanced BCE written out in f64.
fn reference_loss(x: &[f64], t: &[bool], region: &[bool]) -> f64 {
    let bce = |x: f64, t: bool| x.max(0.0) - if t { x } else { 0.0 } + (-x.abs()).exp().ln_1p();
    let mean = |class: bool| {
        let v: Vec<f64> = (0..x.len())
            .filter(|&i| region[i] && t[i] == class)
            .map(|i| bce(x[i], t[i]))
            .collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    };
    let parts: Vec<f64> = [mean(true), mean(false)].into_iter().flatten().collect();
    match parts.len() {
        0 => 0.0,
        n => parts.iter().sum::<f64>() / n as f64,
    }
}

#[test]
fn balanced_bce_matches_its_formula_and_its_finite_differences() {
    let cfg = tiny_volume();
    let n = voxel_count(&cfg);
    let mut r = rng(4);
    let occupied: Vec<bool> = (0..n).map(|_| r.random_bool(0.2)).collect();
    let region: Vec<bool> = (0..n).map(|_| r.random_bool(0.8)).collect();
    let logits = Var::from_tensor(&uniform(&mut r, &cfg.cells, -4.0, 4.0)).unwrap();
    let loss = || occupancy_loss(logits.as_tensor(), &occupied, Some(&region)).unwrap();
    let got = values(&loss())[0];
    let want = reference_loss(&values(logits.as_tensor()), &occupied, &region);
    assert!((got - want).abs() < 1e-12, "{got} vs {want}");
    check_gradients(&[("logits", &logits)], 24, &loss);

    // Logits 0: ln 2 whatever the balance; no region: 0; extreme logits: finite.
    let zeros = Tensor::zeros(&cfg.cells[..], DType::F64, &Device::Cpu).unwrap();
    let l = values(&occupancy_loss(&zeros, &occupied, None).unwrap())[0];
    assert!((l - 2f64.ln()).abs() < 1e-12);
    let nowhere = vec![false; n];
    assert_eq!(
        values(&occupancy_loss(&zeros, &occupied, Some(&nowhere)).unwrap())[0],
        0.0
    );
    let all_free = vec![false; n];
    let l = values(&occupancy_loss(&zeros, &all_free, None).unwrap())[0];
    assert!((l - 2f64.ln()).abs() < 1e-12, "one class only");
    for x in [1e4f32, -1e4, 1e30, -1e30] {
        let big =
            Var::from_tensor(&Tensor::full(x, &cfg.cells[..], &Device::Cpu).unwrap()).unwrap();
        let l = occupancy_loss(big.as_tensor(), &occupied, None).unwrap();
        let v = values(&l)[0];
        assert!(v.is_finite() && (v - x.abs() as f64 / 2.0).abs() <= 1e-3 * x.abs() as f64);
        let g = l.backward().unwrap();
        assert!(values(g.get(big.as_tensor()).unwrap())
            .iter()
            .all(|v| v.is_finite()));
    }
    assert!(occupancy_loss(&zeros, &occupied[1..], None).is_err());
}

/// A fresh directory for one test run.
fn temp_root(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("stereosplat-volume-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn a_bins_lidar_hits_land_in_the_bin_frame_far_from_the_origin() {
    const SEQ: &str = "2013_05_28_drive_0000_sync";
    let (w, h) = (88, 24);
    let root = temp_root("lidar");
    let calib = Calibration::synthetic(w, h);
    let mut writer = SequenceWriter::create(&root, SEQ, &calib).unwrap();
    // Three frames 1e5 m from the origin, turned, each 5 m further along the camera's z.
    let rotation = DQuat::from_rotation_y(-2.0) * DQuat::from_rotation_x(0.02);
    let start = DVec3::new(1.0e5, -1.0e5 + 0.123, 35.0);
    let to_velo = calib.velo_to_rect().inverse();
    let hit = DVec3::new(1.25, 0.75, 10.0); // in each frame's rectified camera 0
    for i in 0..3u32 {
        let pose = DAffine3::from_rotation_translation(
            rotation,
            start + rotation * DVec3::new(0.0, 0.0, 5.0 * i as f64),
        );
        let image = RgbImage::new(w, h);
        let frame = StereoFrame {
            index: i,
            left: image.clone(),
            right: image,
            left_to_world: pose,
        };
        writer
            .write_frame(&frame, 1_000_000_000 * i as i64)
            .unwrap();
        if i < 2 {
            let v = to_velo.transform_point3(hit).as_vec3();
            let scan = [[v.x, v.y, v.z, 0.5], [f32::NAN, 0.0, 0.0, 0.5]];
            writer
                .write_lidar(i, &scan, 1_000_000_000 * i as i64)
                .unwrap();
        }
    }
    writer.finish().unwrap();
    let sequence = Sequence::open(&root, SEQ).unwrap();
    let bin = Bin {
        first: 0,
        centre: 1,
        last: 2,
    };
    let hits = bin_lidar_points(&sequence, &bin);
    assert_eq!(hits.frames_without_scan, 1);
    assert_eq!(hits.points.len(), 2, "the NaN point is dropped");
    for (i, p) in hits.points.iter().enumerate() {
        let want = hit + DVec3::new(0.0, 0.0, 5.0 * i as f64);
        let err = (DVec3::from_array(p.map(f64::from)) - want)
            .abs()
            .max_element();
        assert!(err < 1e-4, "frame {i}: {p:?} vs {want}");
    }
    let cfg = VolumeConfig::tiny();
    let occupied = occupied_voxels(&cfg, &hits.points);
    assert_eq!(occupied.iter().filter(|&&o| o).count(), 2);
    let _ = std::fs::remove_dir_all(&root);
}
