//! The triplane encoder half of the volume branch (`model::net::volume`): the pose code and
//! its SO(3) log map at 0, 1e-8, pi - 1e-6 and pi; cross-image and cross-plane deformable
//! attention against central finite differences in f64; and finite outputs and gradients
//! for a query no view sees, identical left and right views, a bin 1e5 m from the world
//! origin (the same planes as at the origin: the branch works in the bin frame), 1 and K
//! pairs with the same weights, and cameras behind the volume.

use crate::finite_support;

use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{VarBuilder, VarMap};
use finite_support::{assert_finite, assert_finite_gradients};
use glam::{DAffine3, DMat3, DVec3, Quat, Vec3};
use model::frame::{Side, StereoRig};
use model::net::volume::{
    so3_exp, so3_log, CrossImageAttention, CrossPlaneAttention, Plane, PlaneQueries, PoseEncoding,
    TriplaneEncoder, ViewAnchors, VolumeConfig, VolumeLayer,
};
use model::net::Config;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::{Camera, Intrinsics};

const W: u32 = 64;
const H: u32 = 32;
const STRIDE: usize = 4;
const FEATURES: usize = 8;
const BASELINE: f64 = 0.6;

/// A small volume (6 x 3 x 8 cells over tiny's extent), 16 channels, 2 heads.
fn small_volume() -> VolumeConfig {
    VolumeConfig {
        cells: [6, 3, 8],
        channels: 16,
        heads: 2,
        ffn_channels: 24,
        layers: vec![VolumeLayer::Hybrid, VolumeLayer::SelfOnly],
        pillar_points_ground: 3,
        pillar_points_side: 4,
        offsets_per_anchor: 2,
        plane_points: 3,
        ..VolumeConfig::tiny()
    }
}

fn small_config() -> Config {
    Config {
        cost_channels: FEATURES,
        volume: small_volume(),
        ..Config::tiny()
    }
}

fn intrinsics() -> Intrinsics {
    Intrinsics::from_hfov(W, H, 80.0)
}

/// The bin-frame cameras of `pairs` rig poses `ahead` metres apart along the world's
/// forward direction, the bin's origin being the first left camera at world `origin`.
fn rig_cameras(origin: DVec3, pairs: usize, ahead: f64) -> Vec<Camera> {
    let rig = StereoRig {
        intrinsics: intrinsics(),
        baseline: BASELINE,
    };
    // Camera axes in the world: x right = world -y, y down = world -z, z forward = world x.
    let axes = DMat3::from_cols(-DVec3::Y, -DVec3::Z, DVec3::X);
    let bin = DAffine3::from_mat3_translation(axes, origin);
    (0..pairs)
        .flat_map(|k| {
            let pose = DAffine3::from_mat3_translation(axes, origin + DVec3::X * ahead * k as f64);
            [Side::Left, Side::Right].map(|side| rig.local_camera(bin, pose, side))
        })
        .collect()
}

fn random_tensor(rng: &mut ChaCha8Rng, shape: &[usize], dtype: DType) -> Tensor {
    let n: usize = shape.iter().product();
    let data: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
    Tensor::from_vec(data, shape, &Device::Cpu)
        .unwrap()
        .to_dtype(dtype)
        .unwrap()
}

/// Every variable of `varmap` set to random values (the zero-initialised offset and weight
/// projections included, so every path carries a gradient).
fn randomise(varmap: &VarMap, rng: &mut ChaCha8Rng, scale: f64) {
    let data = varmap.data().lock().unwrap();
    let mut names: Vec<&String> = data.keys().collect();
    names.sort(); // the same values for the same seed, whatever the map's order
    for name in names {
        let var = &data[name];
        let t = (random_tensor(rng, var.dims(), var.dtype()) * scale).unwrap();
        var.set(&t).unwrap();
    }
}

fn values(t: &Tensor) -> Vec<f64> {
    t.flatten_all()
        .unwrap()
        .to_dtype(DType::F64)
        .unwrap()
        .to_vec1()
        .unwrap()
}

fn max_abs_diff(a: &Tensor, b: &Tensor) -> f64 {
    values(a)
        .iter()
        .zip(values(b))
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

// ---------------------------------------------------------------- pose code

/// A rotation of `angle` about unit `axis`, built from its quaternion (not from `so3_exp`).
fn rotation(axis: DVec3, angle: f64) -> DMat3 {
    DMat3::from_quat(glam::DQuat::from_axis_angle(axis.normalize(), angle))
}

#[test]
fn so3_log_is_accurate_near_the_identity_and_near_pi() {
    let axes = [
        DVec3::X,
        DVec3::Y,
        DVec3::Z,
        DVec3::new(1.0, -2.0, 0.5).normalize(),
        DVec3::new(-0.3, 0.1, -0.9).normalize(),
    ];
    let pi = std::f64::consts::PI;
    for axis in axes {
        for angle in [0.0, 1e-8, 1e-3, 1.0, pi - 1e-6, pi] {
            let r = rotation(axis, angle);
            let w = so3_log(r);
            assert!(w.is_finite(), "{axis} {angle}: {w}");
            let theta = w.length();
            assert!(
                (theta - angle).abs() <= 1e-12 + 1e-9 * angle,
                "{axis} {angle}: angle {theta}"
            );
            if angle > 0.0 {
                // At exactly pi both signs are the same rotation.
                let along = w.dot(axis) / theta;
                let expected = if angle == pi { along.signum() } else { 1.0 };
                assert!(
                    (along - expected).abs() < 1e-9,
                    "{axis} {angle}: axis {}",
                    w / theta
                );
            }
            // exp(log(R)) = R, at pi too.
            let back = so3_exp(w);
            let err = (back - r)
                .to_cols_array()
                .iter()
                .fold(0f64, |m, v| m.max(v.abs()));
            assert!(err < 1e-12, "{axis} {angle}: round trip off by {err}");
        }
    }
    // log(exp(w)) = w below pi.
    for w in [
        DVec3::ZERO,
        DVec3::new(1e-8, 0.0, 0.0),
        DVec3::new(0.3, -0.2, 0.1),
        DVec3::new(0.0, 0.0, pi - 1e-6),
    ] {
        let back = so3_log(so3_exp(w));
        assert!(
            (back - w).length() <= 1e-9 * (1.0 + w.length()),
            "{w} -> {back}"
        );
    }
}

#[test]
fn pose_code_follows_the_papers_equation() {
    let cfg = VolumeConfig {
        pose_frequencies: 3,
        pose_base: 100.0,
        pose_translation_scale: 0.1,
        pose_rotation_scale: 0.5,
        pose_raw: true,
        ..VolumeConfig::tiny()
    };
    let angle = 0.4;
    let r = rotation(DVec3::Y, angle);
    let t = DVec3::new(2.0, -1.0, 8.0);
    let pe = PoseEncoding::new(&cfg, 64);
    let code = pe.encode_pose(r, t);
    assert_eq!(code.len(), 64);
    let x = [0.2, -0.1, 0.8, 0.0, 0.2, 0.0];
    let tau = 2.0 * std::f64::consts::PI;
    let omega = [tau, tau / 10.0, tau / 100.0];
    for (i, &xi) in x.iter().enumerate() {
        for (m, w) in omega.iter().enumerate() {
            let at = i * 6 + 2 * m;
            // The config's scales are f32 (0.1 is 0.1 + 1.5e-9).
            assert!((code[at] - (w * xi).sin()).abs() < 1e-7, "sin {i} {m}");
            assert!((code[at + 1] - (w * xi).cos()).abs() < 1e-7, "cos {i} {m}");
        }
    }
    for (i, &xi) in x.iter().enumerate() {
        assert!((code[36 + i] - xi).abs() < 1e-7, "raw {i}");
    }
    assert!(code[42..].iter().all(|&v| v == 0.0), "zero padding");
    // Cut to D; no raw part when gamma = 0; M = 1 is the single frequency 2 pi.
    assert_eq!(
        pe.encode_pose(r, t)[..10],
        PoseEncoding::new(&cfg, 10).encode_pose(r, t)[..]
    );
    let plain = VolumeConfig {
        pose_raw: false,
        pose_frequencies: 1,
        ..cfg.clone()
    };
    let code = PoseEncoding::new(&plain, 16).encode_pose(r, t);
    assert!((code[0] - (tau * 0.2).sin()).abs() < 1e-7);
    assert!((code[11] - (tau * 0.0).cos()).abs() < 1e-12);
    assert!(code[12..].iter().all(|&v| v == 0.0));
}

#[test]
fn pose_code_encodes_the_camera_to_bin_pose() {
    let pe = PoseEncoding::new(&VolumeConfig::tiny(), 64);
    let q = Quat::from_rotation_y(0.3);
    let c = Vec3::new(0.6, -0.1, 4.0);
    let camera = Camera::from_camera_to_world(intrinsics(), q, c);
    let expected = pe.encode_pose(DMat3::from_quat(q.as_dquat()), c.as_dvec3());
    let code = pe.encode(&camera);
    for (a, b) in code.iter().zip(&expected) {
        assert!((a - b).abs() < 1e-6, "{code:?} vs {expected:?}");
    }
    let t = pe
        .forward(&[camera, camera], DType::F32, &Device::Cpu)
        .unwrap();
    assert_eq!(t.dims(), &[2, 64]);
}

// ------------------------------------------------------- gradient checks

/// Central finite differences of `loss` at `count` random entries of `var` against the
/// gradient `grad`.
fn check_gradient(
    var: &Var,
    grad: &Tensor,
    loss: &dyn Fn() -> f64,
    rng: &mut ChaCha8Rng,
    count: usize,
    what: &str,
) {
    let g = values(grad);
    let base = values(var.as_tensor());
    let eps = 1e-6;
    let mut checked = 0;
    for _ in 0..count {
        let i = rng.random_range(0..base.len());
        let at = |d: f64| {
            let mut v = base.clone();
            v[i] += d;
            var.set(&Tensor::from_vec(v, var.dims(), &Device::Cpu).unwrap())
                .unwrap();
            loss()
        };
        let fd = (at(eps) - at(-eps)) / (2.0 * eps);
        var.set(&Tensor::from_vec(base.clone(), var.dims(), &Device::Cpu).unwrap())
            .unwrap();
        assert!(
            (fd - g[i]).abs() <= 1e-6 + 1e-5 * fd.abs().max(g[i].abs()),
            "{what}[{i}]: finite difference {fd} vs gradient {}",
            g[i]
        );
        checked += (g[i] != 0.0) as usize;
    }
    assert!(checked > 0, "{what}: every gradient checked is zero");
}

/// Random query tokens of the small volume's planes as variables.
fn query_vars(cfg: &VolumeConfig, rng: &mut ChaCha8Rng) -> [Var; 3] {
    let shapes = cfg.plane_shapes();
    std::array::from_fn(|i| {
        let (r, c) = shapes[i];
        Var::from_tensor(&random_tensor(rng, &[r * c, cfg.channels], DType::F64)).unwrap()
    })
}

/// A fixed random projection of the three planes' tokens to one number.
fn weigh(out: &[Tensor; 3], probes: &[Tensor; 3]) -> Tensor {
    let mut sum = (&out[0] * &probes[0]).unwrap().sum_all().unwrap();
    for i in 1..3 {
        sum = (sum + (&out[i] * &probes[i]).unwrap().sum_all().unwrap()).unwrap();
    }
    sum
}

#[test]
fn cross_image_attention_gradients_match_finite_differences() {
    let cfg = small_volume();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F64, &Device::Cpu);
    let block = CrossImageAttention::new(vb, &cfg).unwrap();
    randomise(&varmap, &mut rng, 0.5);
    let cameras = rig_cameras(DVec3::ZERO, 1, 0.0);
    let anchors = ViewAnchors::all(&cfg, &cameras, STRIDE, DType::F64, &Device::Cpu).unwrap();
    let (h, w) = (H as usize / STRIDE, W as usize / STRIDE);
    let features = Var::from_tensor(&random_tensor(
        &mut rng,
        &[2, cfg.channels, h, w],
        DType::F64,
    ))
    .unwrap();
    let queries = query_vars(&cfg, &mut rng);
    let probes: [Tensor; 3] =
        std::array::from_fn(|i| random_tensor(&mut rng, queries[i].dims(), DType::F64));
    let loss = || {
        let q = queries.each_ref().map(|v| v.as_tensor().clone());
        weigh(
            &block.forward(&q, features.as_tensor(), &anchors).unwrap(),
            &probes,
        )
    };
    let grads = loss().backward().unwrap();
    let scalar = || loss().to_scalar::<f64>().unwrap();
    check_gradient(
        &features,
        grads.get(features.as_tensor()).unwrap(),
        &scalar,
        &mut rng,
        60,
        "features",
    );
    for (i, q) in queries.iter().enumerate() {
        check_gradient(
            q,
            grads.get(q.as_tensor()).unwrap(),
            &scalar,
            &mut rng,
            8,
            &format!("queries {:?}", Plane::ALL[i]),
        );
    }
    // The offset projection gets a gradient (sampling points move with the query).
    let offsets = varmap.data().lock().unwrap()["xz.offsets.weight"].clone();
    let g = grads.get(offsets.as_tensor()).unwrap();
    check_gradient(&offsets, g, &scalar, &mut rng, 6, "xz offsets");
}

#[test]
fn cross_plane_attention_gradients_match_finite_differences() {
    let cfg = small_volume();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F64, &Device::Cpu);
    let block = CrossPlaneAttention::new(vb.pp("planes"), &cfg).unwrap();
    let queries = PlaneQueries::new(vb.pp("queries"), &cfg).unwrap();
    randomise(&varmap, &mut rng, 0.5);
    let tokens = query_vars(&cfg, &mut rng);
    let probes: [Tensor; 3] =
        std::array::from_fn(|i| random_tensor(&mut rng, tokens[i].dims(), DType::F64));
    let loss = || {
        let t = tokens.each_ref().map(|v| v.as_tensor().clone());
        weigh(
            &block.forward(&t, &queries.positions().unwrap()).unwrap(),
            &probes,
        )
    };
    let grads = loss().backward().unwrap();
    let scalar = || loss().to_scalar::<f64>().unwrap();
    for (i, t) in tokens.iter().enumerate() {
        check_gradient(
            t,
            grads.get(t.as_tensor()).unwrap(),
            &scalar,
            &mut rng,
            10,
            &format!("tokens {:?}", Plane::ALL[i]),
        );
    }
    let data = varmap.data().lock().unwrap();
    for name in [
        "queries.xy.row_code",
        "planes.zy.levels.weight",
        "planes.xz.offsets.weight",
    ] {
        let var = data[name].clone();
        check_gradient(
            &var,
            grads.get(var.as_tensor()).unwrap(),
            &scalar,
            &mut rng,
            6,
            name,
        );
    }
}

// ------------------------------------------------------ stability

/// The encoder of [`small_config`] with random weights (f32).
fn encoder(seed: u64) -> (VarMap, TriplaneEncoder) {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    let enc = TriplaneEncoder::new(vb, &small_config()).unwrap();
    randomise(&varmap, &mut ChaCha8Rng::seed_from_u64(seed), 0.3);
    (varmap, enc)
}

fn view_features(views: usize, seed: u64) -> Tensor {
    let (h, w) = (H as usize / STRIDE, W as usize / STRIDE);
    random_tensor(
        &mut ChaCha8Rng::seed_from_u64(seed),
        &[views, FEATURES, h, w],
        DType::F32,
    )
}

/// Forward and backward through the encoder: the planes have the configured shapes, and
/// every output and every gradient (weights and features) is finite. Returns the planes.
fn check_stable(features: &Tensor, cameras: &[Camera], what: &str) -> [Tensor; 3] {
    let (varmap, enc) = encoder(11);
    let features = Var::from_tensor(features).unwrap();
    let planes = enc
        .forward(None, features.as_tensor(), cameras, STRIDE)
        .unwrap();
    let cfg = small_volume();
    for (i, (r, c)) in cfg.plane_shapes().into_iter().enumerate() {
        assert_eq!(planes.0[i].dims(), &[cfg.channels, r, c], "{what}");
        assert_finite(&planes.0[i], what);
    }
    let loss = planes
        .0
        .iter()
        .map(|p| p.sqr().unwrap().mean_all().unwrap())
        .reduce(|a, b| (a + b).unwrap())
        .unwrap();
    let grads = loss.backward().unwrap();
    let with_grad = assert_finite_gradients(&varmap, &grads, what);
    assert!(
        with_grad > 20,
        "{what}: only {with_grad} variables got a gradient"
    );
    if let Some(g) = grads.get(features.as_tensor()) {
        assert_finite(g, &format!("{what}: feature gradient"));
    }
    planes.0
}

#[test]
fn queries_no_view_sees_get_nothing_from_the_images() {
    let cfg = small_volume();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    let block = CrossImageAttention::new(vb, &cfg).unwrap();
    randomise(&varmap, &mut rng, 0.5);
    let cameras = rig_cameras(DVec3::ZERO, 1, 0.0);
    let anchors = ViewAnchors::all(&cfg, &cameras, STRIDE, DType::F32, &Device::Cpu).unwrap();
    let queries: [Tensor; 3] = std::array::from_fn(|i| {
        let (r, c) = cfg.plane_shapes()[i];
        random_tensor(&mut rng, &[r * c, cfg.channels], DType::F32)
    });
    let (h, w) = (H as usize / STRIDE, W as usize / STRIDE);
    let features = random_tensor(&mut rng, &[2, cfg.channels, h, w], DType::F32);
    let out = block.forward(&queries, &features, &anchors).unwrap();
    let (mut unseen, mut seen) = (0, 0);
    for i in 0..3 {
        assert_finite(&out[i], "cida");
        let mask = values(&anchors[i].seen);
        let n = mask.len();
        for (q, &m) in mask.iter().enumerate() {
            let change = max_abs_diff(
                &out[i].narrow(0, q, 1).unwrap(),
                &queries[i].narrow(0, q, 1).unwrap(),
            );
            if m == 0.0 {
                assert_eq!(
                    change, 0.0,
                    "plane {i} query {q} of {n}: unseen but changed"
                );
                unseen += 1;
            } else {
                assert!(change > 0.0, "plane {i} query {q}: seen but unchanged");
                seen += 1;
            }
        }
    }
    // The 80-degree pair sees only part of the 32 m wide volume: both kinds occur.
    assert!(unseen > 10 && seen > 10, "unseen {unseen}, seen {seen}");
    // The encoder stays finite with those queries too.
    check_stable(&view_features(2, 1), &cameras, "partly seen volume");
}

#[test]
fn identical_left_and_right_views_stay_finite() {
    let one = view_features(1, 2);
    let features = Tensor::cat(&[&one, &one], 0).unwrap();
    check_stable(
        &features,
        &rig_cameras(DVec3::ZERO, 1, 0.0),
        "identical views",
    );
}

#[test]
fn a_bin_far_from_the_world_origin_gives_the_planes_of_one_at_the_origin() {
    let features = view_features(4, 3);
    let near = rig_cameras(DVec3::ZERO, 2, 3.0);
    let far = rig_cameras(DVec3::new(1.0e5, -1.0e5, 30.0), 2, 3.0);
    let a = check_stable(&features, &near, "bin at the origin");
    let b = check_stable(&features, &far, "bin 1e5 m out");
    for i in 0..3 {
        let d = max_abs_diff(&a[i], &b[i]);
        assert!(d < 1e-5, "plane {i} differs by {d}");
    }
}

#[test]
fn one_and_several_pairs_go_through_the_same_weights() {
    let (_, enc) = encoder(13);
    let one = view_features(2, 4);
    let cams = rig_cameras(DVec3::ZERO, 1, 0.0);
    let single = enc.forward(None, &one, &cams, STRIDE).unwrap();
    // The same pair given three times: the mean over the views that see a query is unchanged.
    let repeated = Tensor::cat(&[&one, &one, &one], 0).unwrap();
    let thrice: Vec<Camera> = cams.iter().cycle().take(6).copied().collect();
    let same = enc.forward(None, &repeated, &thrice, STRIDE).unwrap();
    for i in 0..3 {
        let d = max_abs_diff(&single.0[i], &same.0[i]);
        assert!(
            d < 1e-5,
            "plane {i}: 1 pair vs the pair thrice differ by {d}"
        );
    }
    // Three different pairs (4 m apart).
    let three = rig_cameras(DVec3::ZERO, 3, 4.0);
    check_stable(&view_features(6, 5), &three, "3 pairs");
    check_stable(&one, &cams, "1 pair");
}

#[test]
fn cameras_behind_the_volume_leave_the_images_out() {
    // Both cameras 60 m forward (the volume ends at 48 m) looking forward: nothing in view.
    let behind: Vec<Camera> = rig_cameras(DVec3::ZERO, 1, 0.0)
        .into_iter()
        .map(|c| Camera {
            position: c.position + Vec3::new(0.0, 0.0, 60.0),
            ..c
        })
        .collect();
    let cfg = small_volume();
    let anchors = ViewAnchors::all(&cfg, &behind, STRIDE, DType::F32, &Device::Cpu).unwrap();
    for a in &anchors {
        assert_eq!(values(&a.seen).iter().sum::<f64>(), 0.0);
    }
    let features = view_features(2, 6);
    let planes = check_stable(&features, &behind, "cameras behind the volume");
    // With no view seeing anything, the images do not matter.
    let (_, enc) = encoder(11);
    let other = enc
        .forward(None, &view_features(2, 7), &behind, STRIDE)
        .unwrap();
    for (a, b) in planes.iter().zip(&other.0) {
        assert!(max_abs_diff(a, b) < 1e-6);
    }
}

#[test]
fn a_prior_of_plane_shapes_moves_the_planes() {
    let (_, enc) = encoder(17);
    let cfg = small_volume();
    let features = view_features(2, 8);
    let cams = rig_cameras(DVec3::ZERO, 1, 0.0);
    let plain = enc.forward(None, &features, &cams, STRIDE).unwrap();
    let prior = model::net::volume::Planes(std::array::from_fn(|i| {
        let (r, c) = cfg.plane_shapes()[i];
        Tensor::ones((cfg.channels, r, c), DType::F32, &Device::Cpu).unwrap()
    }));
    let with = enc.forward(Some(&prior), &features, &cams, STRIDE).unwrap();
    assert!(max_abs_diff(&plain.0[0], &with.0[0]) > 1e-3);
    let tokens = with.to_tokens().unwrap();
    assert_eq!(tokens[2].dims(), &[3 * 8, cfg.channels]);
}
