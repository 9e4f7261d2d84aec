//! The volume branch wired into the network, the reconstructor and training (tiny instance:
//! `volume.cells=[8, 4, 8]`, `volume.top_k=64`): a training step gives a finite loss and a
//! finite gradient in every volume variable, with and without the cost-volume branch's
//! Gaussians (the paper's Branch_3D row); 1 and 2 pairs run with the same weights; cameras
//! that look away from the volume decode nothing and still train without NaN; the shipped
//! tiny weights warm-start the cost-volume part (the volume part fresh) and give its
//! Gaussians exactly as the plain network does.

use crate::drive_support;
use crate::finite_support;

use std::path::PathBuf;

use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use finite_support::{assert_finite, assert_finite_gradients};
use glam::{Quat, Vec3};
use model::lpips::{self, Lpips};
use model::net::volume::voxels::voxel_count;
use model::net::{default_weights, Config, LearnedReconstructor, StereoSplat};
use model::synth::SynthConfig;
use model::train::{losses, DataRoot, LossWeights, Sample, SampleConfig, Target, TrainingSet};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use renderer::{Camera, Intrinsics, RenderSettings};

fn config(settings: &[&str]) -> Config {
    Config::tiny()
        .with_settings(
            &[
                &[
                    "volume_branch=true",
                    "volume.cells=[8, 4, 8]",
                    "volume.top_k=64",
                ][..],
                settings,
            ]
            .concat(),
        )
        .unwrap()
}

fn network(cfg: &Config) -> (VarMap, StereoSplat) {
    let varmap = VarMap::new();
    let net = StereoSplat::new(
        VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu),
        cfg,
    )
    .unwrap();
    (varmap, net)
}

/// A short generated drive (136x40), written once per test process.
fn drive() -> PathBuf {
    let config = SynthConfig {
        seed: 21,
        frames: 24,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    };
    drive_support::once("volume-train", &config).0
}

fn sample_of(cfg: &Config, pairs: usize, seed: u64) -> Sample {
    let data = TrainingSet::open(&[DataRoot::new(drive())], None).unwrap();
    let sample_cfg = SampleConfig {
        max_pairs: pairs,
        subsample_views: pairs > 1,
        targets: 2,
        gaussian_stride: cfg.gaussian_stride,
        volume: Some(cfg.volume.clone()),
    };
    // Subsampling draws 1..=pairs pairs: draw until the sample has exactly `pairs`.
    (seed..)
        .map(|s| {
            data.sample(&mut ChaCha8Rng::seed_from_u64(s), &sample_cfg, &Device::Cpu)
                .unwrap()
        })
        .find(|s| s.cameras.len() == 2 * pairs)
        .unwrap()
}

/// One step: forward, losses, backward; every volume variable gets a finite gradient.
/// Returns (occupancy loss, volume L2, Gaussians the branch decoded).
fn step(cfg: &Config, sample: &Sample, what: &str) -> (f32, f32, usize) {
    let (varmap, net) = network(cfg);
    let prediction = net.forward(&sample.images, &sample.cameras).unwrap();
    let volume = prediction.volume.as_ref().expect("the branch ran");
    assert_finite(&prediction.output().unwrap().pack().unwrap(), what);
    let lpips = Lpips::load(lpips::default_weights(), DType::F32, &Device::Cpu).unwrap();
    let l = losses(
        &prediction,
        sample,
        &lpips,
        &LossWeights::default(),
        &RenderSettings::default(),
        net.config(),
    )
    .unwrap();
    let total = l.total.to_scalar::<f32>().unwrap();
    assert!(
        total.is_finite() && l.occupancy.is_finite() && l.volume_l2.is_finite(),
        "{what}"
    );
    let grads = l.total.backward().unwrap();
    assert_finite_gradients(&varmap, &grads, what);
    let data = varmap.data().lock().unwrap();
    let volume_vars: Vec<_> = data
        .iter()
        .filter(|(k, _)| k.starts_with("volume."))
        .collect();
    assert!(
        volume_vars.len() > 20,
        "{what}: {} volume variables",
        volume_vars.len()
    );
    let without: Vec<&String> = volume_vars
        .iter()
        .filter(|(_, v)| grads.get(v.as_tensor()).is_none())
        .map(|(k, _)| *k)
        .collect();
    if volume.gaussians() > 0 {
        // The fusion adapter sees no cell when no cost-volume Gaussian lands in the volume;
        // everything else must be reached by the losses.
        let missing: Vec<_> = without.iter().filter(|k| !k.contains("fusion")).collect();
        assert!(missing.is_empty(), "{what}: no gradient for {missing:?}");
    }
    (l.occupancy, l.volume_l2, volume.gaussians())
}

#[test]
fn a_training_step_with_the_branch_is_finite_in_every_volume_variable() {
    let cfg = config(&[]);
    let sample = sample_of(&cfg, 1, 5);
    let occupied = sample.occupied.as_ref().unwrap();
    assert_eq!(occupied.len(), voxel_count(&cfg.volume));
    assert!(
        occupied.iter().any(|&o| o),
        "the bin's LiDAR fills some voxel"
    );
    let inside: f32 = sample
        .targets
        .iter()
        .map(|t| {
            t.in_volume
                .as_ref()
                .unwrap()
                .sum_all()
                .unwrap()
                .to_scalar::<f32>()
                .unwrap()
        })
        .sum();
    assert!(inside > 0.0, "some target pixel sees the volume");
    let (occupancy, volume_l2, gaussians) = step(&cfg, &sample, "both branches");
    assert!(
        occupancy > 0.0 && volume_l2 > 0.0,
        "{occupancy} {volume_l2}"
    );
    assert!(gaussians > 0 && gaussians <= 64 * cfg.volume.gaussians_per_voxel);
}

#[test]
fn branch_3d_alone_outputs_only_the_volume_gaussians_and_trains() {
    let cfg = config(&["cost_volume_branch=false"]);
    let sample = sample_of(&cfg, 1, 6);
    let (_, net) = network(&cfg);
    let p = net.forward(&sample.images, &sample.cameras).unwrap();
    let counts = p.counts();
    assert_eq!(counts.cost_volume, 0);
    assert_eq!(p.output().unwrap().means.dim(0).unwrap(), counts.volume);
    assert!(counts.volume > 0);
    step(&cfg, &sample, "branch 3D");
}

#[test]
fn one_and_two_pairs_run_with_the_same_weights() {
    let cfg = config(&[]);
    let (varmap, _) = network(&cfg);
    let mut rec = LearnedReconstructor::from_net(
        StereoSplat::new(
            VarBuilder::from_tensors(frozen(&varmap), DType::F32, &Device::Cpu),
            &cfg,
        )
        .unwrap(),
        0,
    );
    for pairs in [1, 2] {
        let sample = sample_of(&cfg, pairs, 40 + pairs as u64);
        let views = sample.cameras.len() / 2;
        step(&cfg, &sample, &format!("{views} pairs"));
        let images = images_of(&sample);
        let stereo: Vec<_> = (0..views)
            .map(|k| model::reconstruct::StereoView {
                left: &images[2 * k],
                right: &images[2 * k + 1],
                left_camera: sample.cameras[2 * k],
                right_camera: sample.cameras[2 * k + 1],
            })
            .collect();
        use model::reconstruct::Reconstructor;
        let set = rec.reconstruct(&stereo).unwrap();
        let report = rec.last_report().unwrap();
        assert_eq!(
            set.len(),
            report.cost_volume_gaussians + report.volume_gaussians,
            "{views} pairs"
        );
        assert!(report.volume_ms > 0.0);
    }
}

#[test]
fn cameras_looking_away_decode_nothing_and_still_train() {
    let cfg = config(&[]);
    let (w, h) = (136u32, 40u32);
    let k = Intrinsics::from_hfov(w, h, 80.0);
    // Looking down -z: the volume (z 0..48 m ahead of the bin frame) is behind them.
    let away = Quat::from_rotation_y(std::f32::consts::PI);
    let cameras: Vec<Camera> = [0.0, 0.5]
        .iter()
        .map(|&x| Camera::from_camera_to_world(k, away, Vec3::new(x, 0.0, 0.0)))
        .collect();
    let dev = Device::Cpu;
    let image = |seed: f64| {
        (Tensor::arange(0f32, (3 * w * h) as f32, &dev).unwrap() * (0.01 + seed))
            .unwrap()
            .sin()
            .unwrap()
            .affine(0.4, 0.5)
            .unwrap()
            .reshape((3, h as usize, w as usize))
            .unwrap()
    };
    let g = cfg.gaussian_stride;
    let sample = Sample {
        images: Tensor::stack(&[image(0.0), image(0.001)], 0).unwrap(),
        cameras: cameras.clone(),
        input_depth: Tensor::zeros(
            (2, 1, (h as usize).div_ceil(g), (w as usize).div_ceil(g)),
            DType::F32,
            &dev,
        )
        .unwrap(),
        targets: vec![Target {
            camera: cameras[1],
            image: image(0.002),
            depth: Tensor::zeros((h as usize, w as usize), DType::F32, &dev).unwrap(),
            in_volume: Some(Tensor::zeros((h as usize, w as usize), DType::F32, &dev).unwrap()),
        }],
        occupied: Some(vec![false; voxel_count(&cfg.volume)]),
    };
    let (occupancy, volume_l2, gaussians) = step(&cfg, &sample, "looking away");
    assert_eq!((occupancy, volume_l2, gaussians), (0.0, 0.0, 0));
}

#[test]
fn shipped_tiny_weights_warm_start_the_cost_volume_part() {
    let cfg = config(&[]);
    let path = default_weights("tiny");
    let (warm, report) = LearnedReconstructor::warm_start(&cfg, &path).unwrap();
    let file = model::assets::load_tensors(&path, &Device::Cpu).unwrap();
    assert_eq!(report.loaded, file.len());
    assert!(report.unused.is_empty());
    assert!(!report.fresh.is_empty() && report.fresh.iter().all(|n| n.starts_with("volume.")));
    assert_eq!(report.fresh_prefixes(), vec!["volume".to_string()]);
    // The plain network without the branch still loads the same file.
    let plain = LearnedReconstructor::load(&Config::tiny(), &path).unwrap();
    assert!(
        LearnedReconstructor::load(&cfg, &path).is_err(),
        "volume weights are missing"
    );
    let sample = sample_of(&cfg, 1, 7);
    let a = warm
        .net()
        .cost_volume(&sample.images, &sample.cameras)
        .unwrap();
    let b = plain
        .net()
        .forward(&sample.images, &sample.cameras)
        .unwrap();
    assert!(b.volume.is_none());
    let values = |t: &Tensor| t.flatten_all().unwrap().to_vec1::<f32>().unwrap();
    assert_eq!(values(&a.splats.means), values(&b.splats.means));
    assert_eq!(values(&a.splats.colors), values(&b.splats.colors));
}

#[test]
fn volume_fusion_drops_only_volume_gaussians_the_input_views_explain() {
    let (varmap, _) = network(&config(&[]));
    let sample = sample_of(&config(&[]), 1, 7);
    let images = images_of(&sample);
    let view = model::reconstruct::StereoView {
        left: &images[0],
        right: &images[1],
        left_camera: sample.cameras[0],
        right_camera: sample.cameras[1],
    };
    // The same weights under both settings.
    let report = |settings: &[&str]| {
        let cfg = config(settings);
        let tensors = VarBuilder::from_tensors(frozen(&varmap), DType::F32, &Device::Cpu);
        let mut rec = LearnedReconstructor::from_net(StereoSplat::new(tensors, &cfg).unwrap(), 0);
        use model::reconstruct::Reconstructor;
        let set = rec.reconstruct(&[view]).unwrap();
        assert!(set.means.iter().all(|m| m.is_finite()));
        rec.last_report().unwrap()
    };
    // All of the branch's Gaussians (no opacity floor); a margin so wide that anything in
    // an input image counts as explained by these random weights' depth.
    let all = report(&["opacity_floor=0.0"]);
    let fused = report(&["opacity_floor=0.0", "volume_fusion_margin=1000.0"]);
    assert_eq!(all.cost_volume_gaussians, fused.cost_volume_gaussians);
    assert!(
        fused.volume_gaussians < all.volume_gaussians,
        "{all:?} {fused:?}"
    );
}

fn frozen(varmap: &VarMap) -> std::collections::HashMap<String, Tensor> {
    model::net::frozen(varmap).unwrap()
}

/// The sample's input images as `RgbImage`s (the reconstructor's input type).
fn images_of(sample: &Sample) -> Vec<model::frame::RgbImage> {
    let (v, _, h, w) = sample.images.dims4().unwrap();
    (0..v)
        .map(|i| {
            let data = sample
                .images
                .get(i)
                .unwrap()
                .permute((1, 2, 0))
                .unwrap()
                .flatten_all()
                .unwrap()
                .to_vec1::<f32>()
                .unwrap();
            model::frame::RgbImage {
                width: w as u32,
                height: h as u32,
                data,
            }
        })
        .collect()
}
