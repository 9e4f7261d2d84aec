//! `net::volume::VoxelDecoder` and `VolumeHead`: gradients against finite differences; the
//! bounds (centres within 2 voxel sizes of their voxel, scales at most 2 voxel sizes, unit
//! quaternions, colours in [0, 1]) for ordinary, zero, huge inputs; opacity `sigmoid(a)
//! sigmoid(o)` exact as a logit at opacity 0 and 1; no voxel seen gives valid empty tensors;
//! the head decodes `top_k` seen voxels, joins the cost-volume set, and the render's
//! gradient reaches the occupancy logits.

use crate::volume_support;

use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{VarBuilder, VarMap};
use glam::{Quat, Vec3};
use model::net::volume::voxels::voxel_at;
use model::net::volume::{
    frustum_mask, log_sigmoid, product_logit, GaussiansPerBranch, VolumeConfig, VolumeHead,
    VoxelDecoder, MAX_OFFSET, MAX_SCALE,
};
use model::ops::{render, SplatTensors, CH_ALPHA};
use renderer::{Camera, Intrinsics, RenderSettings};
use volume_support::{
    assert_finite, assert_finite_grads, check_gradients, rng, tiny_volume, uniform, values,
};

fn decoder(cfg: &VolumeConfig, dtype: DType) -> (VarMap, VoxelDecoder) {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, dtype, &Device::Cpu);
    let d = VoxelDecoder::new(vb.pp("decoder"), cfg).unwrap();
    (varmap, d)
}

fn planes(cfg: &VolumeConfig, seed: u64, scale: f64) -> [Tensor; 3] {
    let mut r = rng(seed);
    cfg.plane_shapes()
        .map(|(rows, cols)| uniform(&mut r, &[cfg.channels, rows, cols], -scale, scale))
}

fn parts(s: &SplatTensors) -> [&Tensor; 6] {
    [
        &s.means,
        &s.log_scales,
        &s.rotations,
        &s.opacity_logits,
        &s.colors,
        &s.confidences,
    ]
}

/// A weighted sum of every output, weights fixed by `seed`.
fn probe_loss(s: &SplatTensors, seed: u64) -> Tensor {
    let mut r = rng(seed);
    parts(s)
        .into_iter()
        .map(|t| {
            let w = uniform(&mut r, t.dims(), -1.0, 1.0)
                .to_dtype(t.dtype())
                .unwrap();
            (t * w).unwrap().sum_all().unwrap()
        })
        .reduce(|a, b| (a + b).unwrap())
        .unwrap()
}

#[test]
fn decoder_gradients_match_finite_differences() {
    let cfg = tiny_volume();
    let (varmap, decoder) = decoder(&cfg, DType::F64);
    let p = planes(&cfg, 1, 1.0).map(|t| Var::from_tensor(&t).unwrap());
    let occupancy = Var::from_tensor(&uniform(&mut rng(2), &cfg.cells, -3.0, 3.0)).unwrap();
    let voxels = [0, 5, 7, 18, 23];
    let loss = || {
        let planes = [0, 1, 2].map(|i| p[i].as_tensor().clone());
        let s = decoder
            .forward(&planes, occupancy.as_tensor(), &voxels)
            .unwrap();
        probe_loss(&s, 3)
    };
    let weights: Vec<(String, Var)> = varmap
        .data()
        .lock()
        .unwrap()
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let mut vars: Vec<(&str, &Var)> = vec![
        ("xz", &p[0]),
        ("xy", &p[1]),
        ("zy", &p[2]),
        ("occupancy", &occupancy),
    ];
    vars.extend(weights.iter().map(|(k, v)| (k.as_str(), v)));
    let worst = check_gradients(&vars, 16, &loss);
    assert!(worst < 1e-6, "{worst}");
    // Only the decoded voxels' occupancy logits get a gradient.
    let g = values(
        loss()
            .backward()
            .unwrap()
            .get(occupancy.as_tensor())
            .unwrap(),
    );
    for (i, v) in g.iter().enumerate() {
        assert_eq!(*v != 0.0, voxels.contains(&i), "voxel {i}");
    }
}

/// Checks the bounds of every decoded Gaussian of `voxels`.
fn check_bounds(cfg: &VolumeConfig, s: &SplatTensors, voxels: &[usize], what: &str) {
    for t in parts(s) {
        assert_finite(t, what);
    }
    let v = cfg.gaussians_per_voxel;
    assert_eq!(s.means.dims(), [voxels.len() * v, 3], "{what}");
    let size = cfg.cell_size();
    let means = values(&s.means);
    let log_scales = values(&s.log_scales);
    let rotations = values(&s.rotations);
    let colors = values(&s.colors);
    let confidences = values(&s.confidences);
    for (row, &voxel) in voxels
        .iter()
        .flat_map(|f| std::iter::repeat_n(f, v))
        .enumerate()
    {
        let centre = cfg.cell_centre(voxel_at(cfg, voxel));
        for a in 0..3 {
            let limit = MAX_OFFSET * size[a] as f64 * (1.0 + 1e-6);
            let d = (means[row * 3 + a] - centre[a] as f64).abs();
            assert!(d <= limit, "{what}: row {row} axis {a}: {d} > {limit}");
            let scale = log_scales[row * 3 + a].exp();
            assert!(scale <= MAX_SCALE * size[a] as f64 * (1.0 + 1e-6), "{what}");
        }
        let q = &rotations[row * 4..row * 4 + 4];
        let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!((norm - 1.0).abs() < 1e-5, "{what}: |q| = {norm}");
        assert!(colors[row * 3..row * 3 + 3]
            .iter()
            .all(|c| (0.0..=1.0).contains(c)));
        assert!((0.0..=1.0).contains(&confidences[row]));
    }
}

#[test]
fn gaussians_stay_bounded_to_their_voxel_for_any_input() {
    let cfg = tiny_volume();
    let voxels: Vec<usize> = (0..24).collect();
    for dtype in [DType::F64, DType::F32] {
        let (varmap, decoder) = decoder(&cfg, dtype);
        for scale in [0.0, 1.0, 1e3, 1e20] {
            let what = format!("{dtype:?} inputs of {scale}");
            let p = planes(&cfg, 4, scale)
                .map(|t| Var::from_tensor(&t.to_dtype(dtype).unwrap()).unwrap());
            let occ = uniform(&mut rng(5), &cfg.cells, -scale, scale)
                .to_dtype(dtype)
                .unwrap();
            let occ = Var::from_tensor(&occ).unwrap();
            let planes = [0, 1, 2].map(|i| p[i].as_tensor().clone());
            let s = decoder.forward(&planes, occ.as_tensor(), &voxels).unwrap();
            check_bounds(&cfg, &s, &voxels, &what);
            let grads = probe_loss(&s, 6).backward().unwrap();
            let weights: Vec<Var> = varmap.all_vars();
            let mut all: Vec<&Var> = p.iter().chain(weights.iter()).collect();
            all.push(&occ);
            assert_finite_grads(&grads, &all, &what);
        }
    }
}

#[test]
fn opacity_logits_are_exact_at_opacity_zero_and_one() {
    let xs = [-1e30, -1e4, -40.0, -3.0, 0.0, 2.5, 40.0, 1e4, 1e30];
    let n = xs.len();
    let a: Vec<f64> = xs.iter().flat_map(|&x| std::iter::repeat_n(x, n)).collect();
    let b: Vec<f64> = (0..n).flat_map(|_| xs).collect();
    let ta =
        Var::from_tensor(&Tensor::from_vec(a.clone(), (n * n, 1), &Device::Cpu).unwrap()).unwrap();
    let tb =
        Var::from_tensor(&Tensor::from_vec(b.clone(), (n * n, 1), &Device::Cpu).unwrap()).unwrap();
    let logit = product_logit(ta.as_tensor(), tb.as_tensor()).unwrap();
    let got = values(&logit);
    for i in 0..n * n {
        // The logit of sigmoid(a) sigmoid(b): -ln(e^-a + e^-b + e^-(a+b)), in f64 where it fits.
        let (x, y) = (a[i], b[i]);
        let terms = [-x, -y, -x - y];
        let m = terms.iter().cloned().fold(f64::MIN, f64::max);
        let want = -(m + terms.iter().map(|t| (t - m).exp()).sum::<f64>().ln());
        assert!(got[i].is_finite(), "({x}, {y})");
        assert!(
            (got[i] - want).abs() <= 1e-9 * (1.0 + want.abs()),
            "({x}, {y}): {} vs {want}",
            got[i]
        );
    }
    let grads = logit.sum_all().unwrap().backward().unwrap();
    assert_finite_grads(&grads, &[&ta, &tb], "product_logit");
    // ln sigmoid at the extremes.
    let x = Tensor::new(&[-1e30f32, -100.0, 0.0, 100.0, 1e30], &Device::Cpu).unwrap();
    let l = values(&log_sigmoid(&x).unwrap());
    assert_eq!(l[0], -1e30f32 as f64);
    assert!((l[1] + 100.0).abs() < 1e-4 && (l[2] + 2f64.ln()).abs() < 1e-6);
    assert!(l[3] <= 0.0 && l[3] > -1e-6 && l[4] == 0.0);
}

fn volume_head(cfg: &VolumeConfig) -> (VarMap, VolumeHead) {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    let h = VolumeHead::new(vb.pp("volume"), cfg).unwrap();
    (varmap, h)
}

/// x -4..4, y -2..2, z 0..8 in 1 m cells, 8 channels, 2 Gaussians per voxel, top 20.
fn street() -> VolumeConfig {
    VolumeConfig {
        range_min: [-4.0, -2.0, 0.0],
        range_max: [4.0, 2.0, 8.0],
        cells: [8, 4, 8],
        channels: 8,
        gaussians_per_voxel: 2,
        top_k: 20,
        ..VolumeConfig::tiny()
    }
}

fn camera() -> Camera {
    Camera::identity(Intrinsics::from_hfov(64, 32, 90.0))
}

#[test]
fn the_head_decodes_the_top_k_seen_voxels_and_the_render_trains_occupancy() {
    let cfg = street();
    let (_, head) = volume_head(&cfg);
    let p =
        planes(&cfg, 7, 1.0).map(|t| Var::from_tensor(&t.to_dtype(DType::F32).unwrap()).unwrap());
    let planes = [0, 1, 2].map(|i| p[i].as_tensor().clone());
    let out = head.forward(&planes, &[camera()]).unwrap();
    let seen = frustum_mask(&cfg, &[camera()]);
    assert_eq!(out.visible, seen);
    assert_eq!(out.voxels.len(), cfg.top_k);
    assert!(out.voxels.iter().all(|&v| seen[v]));
    // No unselected seen voxel scores higher than a selected one.
    let scores = values(&out.occupancy_logits);
    let lowest = out
        .voxels
        .iter()
        .map(|&v| scores[v])
        .fold(f64::MAX, f64::min);
    for v in (0..seen.len()).filter(|&v| seen[v] && !out.voxels.contains(&v)) {
        assert!(scores[v] <= lowest);
    }
    assert_eq!(out.gaussians(), cfg.top_k * cfg.gaussians_per_voxel);
    check_bounds(&cfg, &out.splats, &out.voxels, "head");

    // Joined with a cost-volume set, rendered: the alpha's gradient reaches the planes and
    // the occupancy logits through the opacity.
    let cv = SplatTensors {
        means: Tensor::new(&[[0f32, 0.0, 5.0], [0.5, 0.2, 6.0]], &Device::Cpu).unwrap(),
        log_scales: Tensor::full(-1f32, (2, 3), &Device::Cpu).unwrap(),
        rotations: Tensor::new(&[[1f32, 0.0, 0.0, 0.0]; 2], &Device::Cpu).unwrap(),
        opacity_logits: Tensor::zeros((2, 1), DType::F32, &Device::Cpu).unwrap(),
        colors: Tensor::full(0.5f32, (2, 3), &Device::Cpu).unwrap(),
        confidences: Tensor::ones((2, 1), DType::F32, &Device::Cpu).unwrap(),
    };
    let counts = GaussiansPerBranch::of(Some(&cv), Some(&out));
    assert_eq!(
        (counts.cost_volume, counts.volume, counts.total()),
        (2, 40, 42)
    );
    let all = SplatTensors::cat(&[&cv, &out.splats]).unwrap();
    let image = render(&all.pack().unwrap(), &camera(), &RenderSettings::default()).unwrap();
    let alpha = image.get(CH_ALPHA).unwrap().sum_all().unwrap();
    let grads = alpha.backward().unwrap();
    let g = values(grads.get(p[0].as_tensor()).unwrap());
    assert!(g.iter().all(|v| v.is_finite()) && g.iter().any(|&v| v != 0.0));

    // The same Gaussians from a decoder whose occupancy logits are a variable: more
    // occupancy, more alpha, for every decoded voxel the image shows.
    let (_, decoder) = decoder(&cfg, DType::F32);
    let occupancy = Var::from_tensor(&out.occupancy_logits.detach()).unwrap();
    let s = decoder
        .forward(&planes, occupancy.as_tensor(), &out.voxels)
        .unwrap();
    let image = render(&s.pack().unwrap(), &camera(), &RenderSettings::default()).unwrap();
    let alpha = image.get(CH_ALPHA).unwrap().sum_all().unwrap();
    let g = values(
        alpha
            .backward()
            .unwrap()
            .get(occupancy.as_tensor())
            .unwrap(),
    );
    let raised: Vec<usize> = (0..g.len()).filter(|&v| g[v] > 0.0).collect();
    assert!(!raised.is_empty() && raised.iter().all(|v| out.voxels.contains(v)));
    assert!(g.iter().all(|&v| v >= 0.0 && v.is_finite()));
}

#[test]
fn no_voxel_seen_gives_valid_empty_tensors() {
    let cfg = street();
    let (_, head) = volume_head(&cfg);
    let planes = planes(&cfg, 8, 1.0).map(|t| t.to_dtype(DType::F32).unwrap());
    let away = Camera::from_camera_to_world(
        camera().intrinsics,
        Quat::from_rotation_y(std::f32::consts::PI),
        Vec3::ZERO,
    );
    let far = Camera::from_camera_to_world(camera().intrinsics, Quat::IDENTITY, Vec3::splat(1e5));
    for cameras in [vec![], vec![away], vec![far, away]] {
        let out = head.forward(&planes, &cameras).unwrap();
        assert!(out.voxels.is_empty() && out.visible.iter().all(|&s| !s));
        assert_eq!(out.gaussians(), 0);
        for (t, k) in parts(&out.splats).into_iter().zip([3, 3, 4, 1, 3, 1]) {
            assert_eq!(t.dims(), [0, k]);
            assert_eq!(t.dtype(), DType::F32);
        }
        // It still joins and renders (nothing).
        let image = render(
            &out.splats.pack().unwrap(),
            &camera(),
            &RenderSettings::default(),
        );
        assert_finite(&image.unwrap(), "empty render");
    }
    // top_k 0 decodes nothing either.
    let none = VolumeConfig {
        top_k: 0,
        ..street()
    };
    let (_, h) = volume_head(&none);
    assert_eq!(h.forward(&planes, &[camera()]).unwrap().gaussians(), 0);
}
