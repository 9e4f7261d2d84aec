//! StereoSplat+'s progressive pass with the shipped `tiny` weights on a generated drive
//! (136x40, never trained on): G_base is kept whole and first, the pseudo pairs add
//! Gaussians at opacity x confidence, the pseudo views go to the bin's known later poses
//! when given (and ahead along the trajectory otherwise), the identity-initialised enhancer
//! gives exactly the raw renders' result, and black, saturated and identical-view inputs
//! give finite maps. `methods::build` makes the pass from settings and names a missing
//! enhancer file.

use crate::drive_support;

use std::path::PathBuf;

use candle_core::{DType, Device};
use candle_nn::{VarBuilder, VarMap};
use model::enhance::{self, Enhancer};
use model::frame::{RgbImage, Side, StereoFrame};
use model::kitti360::Sequence;
use model::methods::{build, MethodError};
use model::net::{default_weights, Config, LearnedReconstructor};
use model::progressive::ProgressiveReconstructor;
use model::reconstruct::{Reconstructor, StereoView};
use model::synth::SynthConfig;
use renderer::{Camera, GaussianSet, RenderWith};

/// A 12-frame drive, written once per test process.
fn drive() -> (PathBuf, String) {
    let config = SynthConfig {
        seed: 1_000_004,
        frames: 12,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    };
    drive_support::once("progressive", &config)
}

/// The first frame, and the bin-local cameras of the first frame and of frames 1..12.
fn bin() -> (StereoFrame, (Camera, Camera), Vec<Camera>) {
    let (root, name) = drive();
    let sequence = Sequence::open(&root, &name).unwrap();
    let rig = sequence.rig();
    let poses = sequence.frames();
    let origin = poses[0].left_to_world;
    let first = sequence.load_frame(poses[0].index).unwrap();
    let cams = (
        rig.local_camera(origin, origin, Side::Left),
        rig.local_camera(origin, origin, Side::Right),
    );
    let ahead = poses[1..]
        .iter()
        .map(|p| rig.local_camera(origin, p.left_to_world, Side::Left))
        .collect();
    (first, cams, ahead)
}

fn view<'a>(left: &'a RgbImage, right: &'a RgbImage, cams: (Camera, Camera)) -> StereoView<'a> {
    StereoView {
        left,
        right,
        left_camera: cams.0,
        right_camera: cams.1,
    }
}

fn learned() -> LearnedReconstructor {
    LearnedReconstructor::load(&Config::tiny(), &default_weights("tiny")).unwrap()
}

/// The pass with the pseudo pairs' fusion margin at 0.1, so that this small bin gets
/// additions (the default, 1, adds none here).
fn pass(enhancer: Option<Enhancer>) -> ProgressiveReconstructor {
    pass_with_margin(enhancer, 0.1)
}

fn pass_with_margin(enhancer: Option<Enhancer>, margin: f32) -> ProgressiveReconstructor {
    let cfg = Config {
        pseudo_fusion_margin: margin,
        ..Config::tiny()
    };
    let learned = LearnedReconstructor::load(&cfg, &default_weights("tiny")).unwrap();
    ProgressiveReconstructor::new(learned, enhancer, RenderWith::Cpu)
}

fn fresh_enhancer() -> Enhancer {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    Enhancer::new(vb, &enhance::Config::tiny()).unwrap()
}

fn assert_finite(set: &GaussianSet, what: &str) {
    set.check_lengths().unwrap();
    let finite = set.means.iter().all(|m| m.is_finite())
        && set.log_scales.iter().all(|s| s.is_finite())
        && set.rotations.iter().all(|q| q.is_finite())
        && set.colors.iter().all(|c| c.is_finite())
        && set
            .opacities
            .iter()
            .chain(&set.confidences)
            .all(|v| v.is_finite() && (0.0..=1.0).contains(v));
    assert!(finite, "{what}: a non-finite Gaussian");
}

#[test]
fn the_pass_keeps_g_base_first_and_adds_confidence_weighted_pseudo_gaussians() {
    let (frame, cams, ahead) = bin();
    let views = [view(&frame.left, &frame.right, cams)];
    let base = learned().reconstruct(&views).unwrap();
    let mut raw = pass(None);
    let out = raw.reconstruct_ahead(&views, &ahead).unwrap();
    let report = raw.last_report().unwrap();
    assert_eq!(raw.name(), "stereosplat-tiny+raw");
    assert_eq!(report.pseudo_pairs, 2);
    assert_eq!(report.base_gaussians, base.len());
    assert_eq!(out.len(), base.len() + report.added_gaussians);
    // Fewer than the two pseudo pairs' grids (4 views of 68x20): fusion dropped what G_base
    // explains.
    assert!(
        report.added_gaussians > 100 && report.added_gaussians < 4 * 68 * 20 * 3 / 4,
        "{report:?}"
    );
    // G_base untouched, first.
    assert_eq!(out.means[..base.len()], base.means[..]);
    assert_eq!(out.opacities[..base.len()], base.opacities[..]);
    // Every addition is at most as opaque as its confidence allows.
    assert!((base.len()..out.len()).all(|i| out.opacities[i] <= out.confidences[i] + 1e-6));
    assert_finite(&out, "raw pass");

    // A wider margin explains more by G_base and adds fewer.
    let mut wide = pass_with_margin(None, 1.0);
    wide.reconstruct_ahead(&views, &ahead).unwrap();
    assert!(wide.last_report().unwrap().added_gaussians < report.added_gaussians / 2);

    // Without known poses the pseudo pairs go ahead along the camera's axis: another map.
    let ahead_only = raw.reconstruct(&views).unwrap();
    assert_eq!(raw.last_report().unwrap().pseudo_pairs, 2);
    assert_ne!(ahead_only.len(), out.len());

    // The enhancer starts as the identity: the same map as the raw renders give.
    let mut enhanced = pass(Some(fresh_enhancer()));
    assert_eq!(enhanced.name(), "stereosplat-tiny+");
    let same = enhanced.reconstruct_ahead(&views, &ahead).unwrap();
    // (Equal up to float rounding: the enhancer's output tensor is laid out differently.)
    assert_eq!(same.len(), out.len());
    assert!((0..out.len()).all(|i| {
        let (a, b) = (same.get(i), out.get(i));
        (a.mean - b.mean).abs().max_element() < 1e-3 && (a.opacity - b.opacity).abs() < 1e-4
    }));
    let split = enhanced.last_split().unwrap();
    assert!(
        split.enhance_ms > 0.0 && split.base_ms > 0.0 && split.plus_ms > 0.0,
        "{split:?}"
    );
    assert_eq!(raw.last_split().unwrap().enhance_ms, 0.0);
    assert_eq!(learned().last_split(), None);
}

#[test]
fn black_saturated_and_identical_views_give_finite_maps() {
    let (frame, cams, ahead) = bin();
    let (w, h) = (frame.left.width, frame.left.height);
    let flat = |v: f32| RgbImage {
        width: w,
        height: h,
        data: vec![v; 3 * (w * h) as usize],
    };
    let (black, white) = (flat(0.0), flat(1.0));
    let mut nan = flat(0.5);
    nan.data[7] = f32::NAN;
    let mut p = pass(Some(fresh_enhancer()));
    for (what, left, right) in [
        ("black", &black, &black),
        ("saturated", &white, &white),
        ("identical", &frame.left, &frame.left),
        ("a NaN pixel", &nan, &nan),
    ] {
        let out = p
            .reconstruct_ahead(&[view(left, right, cams)], &ahead)
            .unwrap();
        assert_finite(&out, what);
        assert!(out.len() <= Config::tiny().max_gaussians);
    }
}

#[test]
fn pseudo_views_behind_far_outside_or_of_an_empty_map_are_harmless() {
    let (frame, cams, _) = bin();
    let views = [view(&frame.left, &frame.right, cams)];
    let base_len = learned().reconstruct(&views).unwrap().len();
    // Pairs 20 m behind the input and 1e4 m ahead (far outside every Gaussian): the renders
    // are mostly empty (all transparent), the enhancer and the network still give finite maps
    // and G_base stays whole.
    let cfg = Config::tiny()
        .with_settings(&["pseudo_poses=[-20.0, 10000.0]"])
        .unwrap();
    let inner = LearnedReconstructor::load(&cfg, &default_weights("tiny")).unwrap();
    let mut p = ProgressiveReconstructor::new(inner, Some(fresh_enhancer()), RenderWith::Cpu);
    let out = p.reconstruct(&views).unwrap();
    assert_eq!(p.last_report().unwrap().pseudo_pairs, 2);
    assert!(out.len() >= base_len);
    assert_finite(&out, "behind and far");
    // G_base empty (a budget of 0): nothing to render, nothing may be added, no error.
    let cfg = Config::tiny().with_settings(&["max_gaussians=0"]).unwrap();
    let inner = LearnedReconstructor::load(&cfg, &default_weights("tiny")).unwrap();
    let mut p = ProgressiveReconstructor::new(inner, Some(fresh_enhancer()), RenderWith::Cpu);
    assert!(p.reconstruct(&views).unwrap().is_empty());
}

#[test]
fn every_nth_bin_gets_the_pass_when_asked() {
    let (frame, cams, ahead) = bin();
    let views = [view(&frame.left, &frame.right, cams)];
    let base = learned().reconstruct(&views).unwrap();
    let cfg = Config::tiny()
        .with_settings(&["progressive_every=3"])
        .unwrap();
    let inner = LearnedReconstructor::load(&cfg, &default_weights("tiny")).unwrap();
    let mut p = ProgressiveReconstructor::new(inner, None, RenderWith::Cpu);
    let passes: Vec<usize> = (0..4)
        .map(|_| {
            let out = p.reconstruct_ahead(&views, &ahead).unwrap();
            let report = p.last_report().unwrap();
            if report.pseudo_pairs == 0 {
                assert_eq!(out, base);
            }
            report.pseudo_pairs
        })
        .collect();
    assert_eq!(passes, [2, 0, 0, 2]);
}

#[test]
fn settings_build_the_pass_and_a_missing_enhancer_is_named() {
    let raw = build(
        "stereosplat",
        None,
        None,
        &["progressive=true".into(), "enhancer=false".into()],
    )
    .unwrap();
    assert_eq!(raw.name(), "stereosplat-tiny+raw");
    let missing = std::env::temp_dir().join("no-such-enhancer.safetensors");
    let err = build(
        "stereosplat",
        None,
        None,
        &[
            "progressive=true".into(),
            format!("enhancer_weights={}", missing.display()),
        ],
    )
    .err()
    .unwrap();
    assert!(matches!(&err, MethodError::Enhancer { path, .. } if *path == missing));
    assert!(err.to_string().contains("enhancer=false"), "{err}");
    // The tiny-plus preset: tiny's weights with the pass on (here without the enhancer).
    let preset = Config::preset("tiny-plus").unwrap();
    assert!(preset.progressive && preset.enhancer);
    assert_eq!(
        preset.pseudo_poses,
        [8.0],
        "one pseudo pair keeps the node real time"
    );
    assert_eq!(default_weights("tiny-plus"), default_weights("tiny"));
    let plus = build(
        "stereosplat",
        Some("tiny-plus"),
        None,
        &["enhancer=false".into()],
    );
    assert_eq!(plus.unwrap().name(), "stereosplat-tiny-plus+raw");
    // Off by default: the plain network.
    assert_eq!(
        build("stereosplat", None, None, &[]).unwrap().name(),
        "stereosplat-tiny"
    );
}
