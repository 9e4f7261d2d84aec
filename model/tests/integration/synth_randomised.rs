//! The generator's domain randomisation: each drive draws its own rig and look from its
//! seed, deterministically; the stereo geometry stays exact under every camera effect; and
//! floating textured objects come close to the camera.

use model::kitti360::Calibration;
use model::synth::{Randomisation, SurfaceClass, SynthConfig, SynthSequence};

fn randomised(seed: u64, frames: u32) -> SynthSequence {
    let config = SynthConfig {
        seed,
        frames,
        randomise: Some(Randomisation::default()),
        ..SynthConfig::default()
    };
    let look = config.look().expect("randomised");
    let calibration = Calibration::synthetic_rig(look.size, look.focal_px, look.baseline_m);
    SynthSequence::new(config, calibration.rig().unwrap(), calibration.cam_to_velo)
}

#[test]
fn a_randomised_drive_is_reproducible_and_has_its_own_rig() {
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let a = randomised(101, 3).frame(2);
    let b = randomised(101, 3).frame(2);
    assert_eq!(bits(&a.frame.left.data), bits(&b.frame.left.data));
    assert_eq!(bits(&a.frame.right.data), bits(&b.frame.right.data));

    let mut sizes = std::collections::BTreeSet::new();
    let mut baselines = Vec::new();
    for seed in 100..116 {
        let seq = randomised(seed, 1);
        let look = seq.config().look().unwrap();
        let rig = seq.rig();
        assert_eq!((rig.intrinsics.width, rig.intrinsics.height), look.size);
        assert!((rig.intrinsics.fx as f64 - look.focal_px).abs() < 1e-3);
        assert!((rig.baseline - look.baseline_m).abs() < 1e-9);
        sizes.insert(look.size);
        baselines.push(look.baseline_m);
        if seed % 4 != 0 {
            continue;
        }
        let f = seq.frame(0);
        assert_eq!((f.frame.left.width, f.frame.left.height), look.size);
        assert!(f
            .frame
            .left
            .data
            .iter()
            .chain(&f.frame.right.data)
            .all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
    }
    eprintln!("sizes {sizes:?}, baselines {baselines:?}");
    assert!(sizes.len() >= 4, "rigs of several image sizes: {sizes:?}");
    let (lo, hi) = baselines
        .iter()
        .fold((f64::MAX, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(lo < 0.15 && hi > 0.3, "baselines {lo}..{hi}");
}

/// Median over the left image's textured pixels (those differing from their neighbour 4 px
/// to the right) of |left - right| sampled where the left pixel's disparity plus `shift`
/// points.
fn stereo_error(seq: &SynthSequence, frame: usize, shift: f64) -> f64 {
    let f = seq.frame(frame);
    let rig = seq.rig();
    let (w, h) = (f.frame.left.width, f.frame.left.height);
    let mut diffs = Vec::new();
    for v in 0..h {
        for u in 0..w {
            let d = f.left_depth.data[(v * w + u) as usize] as f64;
            if d <= 0.0 {
                continue;
            }
            let ur = (u as f64 - rig.intrinsics.fx as f64 * rig.baseline / d + shift).round();
            if ur < 0.0 || ur > (w - 1) as f64 {
                continue;
            }
            let l = f.frame.left.pixel(u, v);
            let next = f.frame.left.pixel((u + 4).min(w - 1), v);
            if (0..3).map(|c| (l[c] - next[c]).abs()).sum::<f32>() < 0.15 {
                continue;
            }
            let r = f.frame.right.pixel(ur as u32, v);
            diffs.push((0..3).map(|c| (l[c] - r[c]).abs() as f64).sum::<f64>() / 3.0);
        }
    }
    assert!(
        diffs.len() > (w * h / 20) as usize,
        "{} textured pixels",
        diffs.len()
    );
    diffs.sort_by(f64::total_cmp);
    diffs[diffs.len() / 2]
}

#[test]
fn stereo_geometry_holds_under_every_camera_effect() {
    for seed in [100, 107] {
        let seq = randomised(seed, 8);
        let right = stereo_error(&seq, 5, 0.0);
        let wrong = stereo_error(&seq, 5, 4.0);
        eprintln!("seed {seed}: median |left - right| {right:.4}, 4 px off {wrong:.4}");
        assert!(right < 0.06, "seed {seed}: {right}");
        assert!(right < 0.6 * wrong, "seed {seed}: {right} vs {wrong}");
    }
}

#[test]
fn floating_objects_come_within_a_few_metres() {
    let mut nearest = f64::MAX;
    let mut floater_pixels = 0usize;
    for seed in [100, 102] {
        let seq = randomised(seed, 60);
        for i in (0..60).step_by(10) {
            let classes = seq.left_classes(i);
            let depth = seq.frame(i).left_depth;
            for (c, d) in classes.iter().zip(&depth.data) {
                if *c == SurfaceClass::Floater {
                    floater_pixels += 1;
                    nearest = nearest.min(*d as f64);
                }
            }
        }
    }
    eprintln!("floater pixels {floater_pixels}, nearest {nearest:.2} m");
    assert!(floater_pixels > 500, "{floater_pixels}");
    assert!(nearest < 3.0, "nearest floater {nearest} m");
}

#[test]
fn the_plain_generator_is_untouched_by_the_randomisation_code() {
    // A plain drive never sees a floater or a photo: every class it shows is the street's.
    let config = SynthConfig {
        seed: 3,
        frames: 40,
        ..SynthConfig::default()
    };
    assert!(config.look().is_none());
    assert_eq!(config.size(), (272, 72));
    let calibration = Calibration::synthetic(272, 72);
    let seq = SynthSequence::new(config, calibration.rig().unwrap(), calibration.cam_to_velo);
    for i in [0, 20, 39] {
        assert!(!seq.left_classes(i).contains(&SurfaceClass::Floater));
    }
}

#[test]
fn a_folder_of_randomised_roots_is_one_training_set() {
    use model::train::{DataRoot, SampleConfig, TrainingSet};
    use rand::SeedableRng;

    let dir = std::env::temp_dir().join(format!("randomised_roots_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut sizes = Vec::new();
    for seed in [100u64, 101] {
        let config = SynthConfig {
            seed,
            frames: 24,
            randomise: Some(Randomisation::default()),
            ..SynthConfig::default()
        };
        sizes.push(config.size());
        let root = dir.join(format!("rand_{seed}"));
        model::generate::write_synthetic(&root, &config, &mut |_, _| {}).unwrap();
    }
    assert_ne!(sizes[0], sizes[1], "the two drives have different rigs");
    // Two rigs in one root are refused: each randomised drive is its own root.
    let clash = SynthConfig {
        seed: 102,
        frames: 2,
        randomise: Some(Randomisation::default()),
        ..SynthConfig::default()
    };
    assert!(
        model::generate::write_synthetic(&dir.join("rand_100"), &clash, &mut |_, _| {}).is_err()
    );

    let set = TrainingSet::open(&[DataRoot::new(&dir)], None).unwrap();
    assert!(!set.is_empty());
    let cfg = SampleConfig {
        max_pairs: 1,
        subsample_views: false,
        targets: 1,
        gaussian_stride: 2,
        volume: None,
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mut seen = std::collections::BTreeSet::new();
    for _ in 0..12 {
        let sample = set
            .sample(&mut rng, &cfg, &candle_core::Device::Cpu)
            .unwrap();
        let (_, _, h, w) = sample.images.dims4().unwrap();
        seen.insert((w as u32, h as u32));
    }
    assert_eq!(seen.len(), 2, "samples come from both rigs: {seen:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}
