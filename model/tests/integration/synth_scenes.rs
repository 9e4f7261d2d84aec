//! The generator's scene kinds at every scale: a desk (0.2-1 m, disparities over 150 px), a
//! room (1-10 m) and a street (as before), each with exact depth in its range, stereo
//! geometry that holds, the KITTI-360 layout the training and evaluation readers take, and
//! clear errors or finite output at the extremes (a surface at 0.1 m, baselines of 1 mm and
//! 2 m, black and saturated images).

use candle_core::Device;
use model::bins::BinConfig;
use model::frame::Side;
use model::generate::{calibration, scene_sequence_name, write_synthetic, GenerateError};
use model::kitti360::Sequence;
use model::synth::{
    Randomisation, RigChoice, SceneKind, SurfaceClass, SynthConfig, SynthConfigError, SynthFrame,
    SynthSequence,
};
use model::train::{DataError, DataRoot, SampleConfig, TrainingSet};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// An unrandomised sequence of `kind` at `width` x `height` with `rig` (the kind's own when
/// `None`), one sample per pixel.
fn config(kind: SceneKind, seed: u64, size: (u32, u32), rig: Option<RigChoice>) -> SynthConfig {
    SynthConfig {
        seed,
        frames: 4,
        width: size.0,
        height: size.1,
        supersample: 1,
        lidar_azimuth_steps: 256,
        scene: kind,
        rig,
        ..SynthConfig::default()
    }
}

fn sequence(config: SynthConfig) -> SynthSequence {
    let calibration = calibration(&config);
    SynthSequence::new(config, calibration.rig().unwrap(), calibration.cam_to_velo)
}

fn rig(baseline_m: f64) -> Option<RigChoice> {
    Some(RigChoice {
        hfov_deg: 70.0,
        baseline_m,
    })
}

/// Share of the pixels with a depth (> 0) that lie in `[lo, hi]`, and how many have one.
fn share_in(frame: &SynthFrame, lo: f32, hi: f32) -> (f64, usize) {
    let valid: Vec<f32> = frame
        .left_depth
        .data
        .iter()
        .copied()
        .filter(|&d| d > 0.0)
        .collect();
    let inside = valid.iter().filter(|&&d| (lo..=hi).contains(&d)).count();
    (inside as f64 / valid.len().max(1) as f64, valid.len())
}

/// Every value finite, images in [0, 1], depths >= 0.
fn assert_finite(frame: &SynthFrame) {
    let images = frame.frame.left.data.iter().chain(&frame.frame.right.data);
    assert!(images
        .clone()
        .all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
    let depths = frame.left_depth.data.iter().chain(&frame.right_depth.data);
    assert!(depths.clone().all(|d| d.is_finite() && *d >= 0.0));
    assert!(frame.lidar.iter().flatten().all(|v| v.is_finite()));
    assert!(frame.frame.left_to_world.is_finite());
}

/// Median |left - right| over textured left pixels, the right image sampled `shift` pixels
/// off the exact disparity (textured: the pixel differs from its neighbour 3 px right).
fn stereo_error(frame: &SynthFrame, fx: f64, baseline: f64, shift: f64) -> f64 {
    let (w, h) = (frame.frame.left.width, frame.frame.left.height);
    let mut diffs = Vec::new();
    for v in 0..h {
        for u in 0..w - 3 {
            let d = frame.left_depth.data[(v * w + u) as usize] as f64;
            if d <= 0.0 {
                continue;
            }
            let ur = (u as f64 - fx * baseline / d + shift).round();
            if ur < 0.0 || ur > (w - 1) as f64 {
                continue;
            }
            let l = frame.frame.left.pixel(u, v);
            let next = frame.frame.left.pixel(u + 3, v);
            if (0..3).map(|c| (l[c] - next[c]).abs()).sum::<f32>() < 0.1 {
                continue;
            }
            let r = frame.frame.right.pixel(ur as u32, v);
            diffs.push((0..3).map(|c| (l[c] - r[c]).abs() as f64).sum::<f64>() / 3.0);
        }
    }
    assert!(diffs.len() > 200, "{} textured pixels", diffs.len());
    diffs.sort_by(f64::total_cmp);
    diffs[diffs.len() / 2]
}

#[test]
fn a_desk_pair_is_at_desk_range_with_large_disparities() {
    let seq = sequence(config(SceneKind::Desk, 11, (640, 480), rig(0.10)));
    let k = seq.rig().intrinsics;
    assert_eq!((k.width, k.height), (640, 480));
    assert!((seq.rig().baseline - 0.10).abs() < 1e-12);
    let frame = seq.frame(2);
    assert_finite(&frame);
    let (share, valid) = share_in(&frame, 0.2, 1.0);
    let disparities: Vec<f64> = frame
        .left_depth
        .data
        .iter()
        .filter(|&&d| d > 0.0)
        .map(|&d| k.fx as f64 * 0.10 / d as f64)
        .collect();
    let over_150 = disparities.iter().filter(|&&d| d > 150.0).count();
    let largest = disparities.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "desk: {valid} px with depth, {:.1}% in 0.2-1 m, {over_150} px over 150 px of \
         disparity, largest {largest:.0} px",
        100.0 * share
    );
    assert_eq!(valid, 640 * 480, "every pixel sees a surface indoors");
    assert!(share > 0.75, "{share}");
    assert!(over_150 > 2000, "{over_150} pixels over 150 px");
    assert!(largest < 640.0 / 2.0, "{largest}");
    let classes = seq.left_classes(2);
    for class in [SurfaceClass::Table, SurfaceClass::Item] {
        let n = classes.iter().filter(|&&c| c == class).count();
        assert!(n > 1000, "{class:?}: {n} px");
    }
    // The right image is the left one moved by the exact disparity.
    let fx = k.fx as f64;
    let right = stereo_error(&frame, fx, 0.10, 0.0);
    let wrong = stereo_error(&frame, fx, 0.10, 5.0);
    eprintln!("desk stereo: median |left - right| {right:.4}, 5 px off {wrong:.4}");
    assert!(right < 0.02 && right < 0.5 * wrong, "{right} vs {wrong}");
}

#[test]
fn desks_show_hands_and_every_seed_stays_at_desk_range() {
    let mut hand = 0;
    for seed in 0..8 {
        let seq = sequence(config(SceneKind::Desk, seed, (160, 120), None));
        let frame = seq.frame(3);
        assert_finite(&frame);
        let (share, _) = share_in(&frame, 0.15, 1.0);
        let nearest = frame
            .left_depth
            .data
            .iter()
            .copied()
            .fold(f32::MAX, f32::min);
        eprintln!(
            "desk seed {seed}: {:.1}% in 0.15-1 m, nearest {nearest:.3} m",
            100.0 * share
        );
        assert!(share > 0.7, "seed {seed}: {share}");
        assert!(nearest > 0.05, "seed {seed}: {nearest}");
        hand += seq
            .left_classes(3)
            .iter()
            .filter(|&&c| c == SurfaceClass::Hand)
            .count();
    }
    assert!(hand > 50, "hands seen: {hand} px");
}

#[test]
fn a_room_pair_is_at_room_range() {
    let mut classes = std::collections::BTreeSet::new();
    for seed in [5, 6, 7] {
        let seq = sequence(config(SceneKind::Room, seed, (320, 240), None));
        let frame = seq.frame(3);
        assert_finite(&frame);
        let (share, valid) = share_in(&frame, 1.0, 10.0);
        let far = frame.left_depth.data.iter().copied().fold(0.0f32, f32::max);
        eprintln!(
            "room seed {seed}: {:.1}% in 1-10 m, farthest {far:.2} m",
            100.0 * share
        );
        assert_eq!(valid, 320 * 240);
        assert!(share > 0.9, "seed {seed}: {share}");
        assert!(far < 11.0, "seed {seed}: {far}");
        classes.extend(seq.left_classes(3));
        let fx = seq.rig().intrinsics.fx as f64;
        let b = seq.rig().baseline;
        let right = stereo_error(&frame, fx, b, 0.0);
        let wrong = stereo_error(&frame, fx, b, 4.0);
        assert!(right < 0.03 && right < 0.6 * wrong, "{right} vs {wrong}");
    }
    eprintln!("room classes {classes:?}");
    for class in [
        SurfaceClass::Floor,
        SurfaceClass::Wall,
        SurfaceClass::Furniture,
    ] {
        assert!(classes.contains(&class), "{class:?} in {classes:?}");
    }
}

#[test]
fn a_street_pair_is_at_street_range() {
    let seq = sequence(config(SceneKind::Street, 3, (272, 72), None));
    assert!((seq.rig().baseline - 0.594).abs() < 1e-3, "KITTI-360's rig");
    let frame = seq.frame(3);
    assert_finite(&frame);
    let (share, valid) = share_in(&frame, 1.0, 100.0);
    eprintln!(
        "street: {valid} px with depth, {:.1}% in 1-100 m",
        100.0 * share
    );
    assert!(share > 0.9, "{share}");
    assert!(valid < 272 * 72, "the sky has no depth");
}

#[test]
fn handheld_paths_move_centimetres_per_frame() {
    for (kind, lo, hi) in [
        (SceneKind::Desk, 0.002, 0.045),
        (SceneKind::Room, 0.005, 0.11),
    ] {
        let seq = sequence(SynthConfig {
            frames: 100,
            ..config(kind, 4, (64, 48), None)
        });
        let steps: Vec<f64> = (0..99)
            .map(|i| (seq.pose(i + 1).translation - seq.pose(i).translation).length())
            .collect();
        let mean = steps.iter().sum::<f64>() / steps.len() as f64;
        let turn = (0..99)
            .map(|i| {
                let r = seq.pose(i).matrix3.transpose() * seq.pose(i + 1).matrix3;
                ((r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) / 2.0)
                    .clamp(-1.0, 1.0)
                    .acos()
            })
            .fold(0.0, f64::max);
        eprintln!(
            "{kind:?}: mean step {mean:.4} m, largest turn {:.2} deg",
            turn.to_degrees()
        );
        assert!(
            mean > lo && steps.iter().all(|&s| s < hi),
            "{kind:?}: {steps:?}"
        );
        assert!(turn < 2f64.to_radians(), "{kind:?}: {turn}");
    }
}

#[test]
fn equal_seeds_give_equal_bits_for_every_kind() {
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for kind in [SceneKind::Desk, SceneKind::Room] {
        let randomised = SynthConfig {
            randomise: Some(Randomisation::for_scene(kind)),
            ..config(kind, 9, (0, 0), None)
        };
        let small = SynthConfig {
            randomise: Some(Randomisation {
                sizes: &[(96, 72)],
                ..Randomisation::for_scene(kind)
            }),
            ..randomised
        };
        let a = sequence(small).frame(1);
        let b = sequence(small).frame(1);
        assert_eq!(bits(&a.frame.left.data), bits(&b.frame.left.data));
        assert_eq!(bits(&a.frame.right.data), bits(&b.frame.right.data));
        assert_eq!(bits(&a.left_depth.data), bits(&b.left_depth.data));
        assert_eq!(a.lidar, b.lidar);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let single = pool.install(|| sequence(small).frame(1));
        assert_eq!(bits(&a.frame.left.data), bits(&single.frame.left.data));
        let other = sequence(SynthConfig { seed: 10, ..small }).frame(1);
        assert_ne!(a.frame.left.data, other.frame.left.data);
        // The randomised rig is drawn from the handheld ranges.
        let look = randomised.look().unwrap();
        assert!((0.05..=0.5).contains(&look.baseline_m));
        assert!((320..=1408).contains(&look.size.0));
    }
}

#[test]
fn rigs_of_5_and_50_cm_are_written_and_read_back_for_training() {
    let dir = std::env::temp_dir().join(format!("stereosplat-scenes-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut largest = Vec::new();
    for (kind, baseline) in [(SceneKind::Desk, 0.05), (SceneKind::Room, 0.5)] {
        let root = dir.join(kind.name());
        let cfg = SynthConfig {
            frames: 12,
            ..config(kind, 21, (160, 120), rig(baseline))
        };
        let name = write_synthetic(&root, &cfg, &mut |_, _| {}).unwrap();
        assert_eq!(name, scene_sequence_name(kind, 21));
        let seq = Sequence::open(&root, &name).unwrap();
        assert!((seq.rig().baseline - baseline).abs() < 1e-9);
        assert_eq!(seq.frames().len(), 12);
        let frame = seq.load_frame(6).unwrap();
        assert_eq!((frame.left.width, frame.left.height), (160, 120));
        let exact = seq
            .exact_depth(6, Side::Left)
            .unwrap()
            .expect("exact depth");
        let lidar = seq.lidar_depth(6, Side::Left).unwrap();
        // The LiDAR-like sweep lands in the image and agrees with the exact depth.
        let mut agree = 0;
        let mut points = 0;
        for (l, e) in lidar.data.iter().zip(&exact.data) {
            if *l > 0.0 && *e > 0.0 {
                points += 1;
                agree += ((l - e).abs() < 0.02 * e + 0.01) as usize;
            }
        }
        eprintln!("{kind:?}: {points} LiDAR pixels, {agree} agree with the exact depth");
        assert!(points > 100, "{points}");
        assert!(agree as f64 > 0.8 * points as f64, "{agree} of {points}");
        let fx = seq.rig().intrinsics.fx as f64;
        let near = exact
            .data
            .iter()
            .copied()
            .filter(|&d| d > 0.0)
            .fold(f32::MAX, f32::min);
        largest.push(fx * baseline / near as f64);
    }
    eprintln!(
        "largest disparities: 5 cm desk {:.0} px, 50 cm room {:.0} px",
        largest[0], largest[1]
    );
    assert!(largest.iter().all(|&d| d > 5.0 && d < 160.0), "{largest:?}");
    // The training reader cuts handheld sequences into short bins and samples them (these
    // 12-frame sequences move a few centimetres).
    let root = |kind: SceneKind, length_m: f64| DataRoot {
        path: dir.join(kind.name()),
        bins: BinConfig {
            length_m,
            ..BinConfig::default()
        },
    };
    let open = |roots: &[DataRoot]| TrainingSet::open(roots, None);
    let desks = open(&[root(SceneKind::Desk, 0.02)]).unwrap().len();
    let rooms = open(&[root(SceneKind::Room, 0.1)]).unwrap().len();
    assert!(desks >= 2, "{desks} desk bins");
    // A mix cuts each root with its own length and draws the roots equally often.
    let mix = open(&[root(SceneKind::Desk, 0.02), root(SceneKind::Room, 0.1)]).unwrap();
    assert_eq!(mix.len(), desks + rooms);
    let sample_cfg = SampleConfig {
        max_pairs: 1,
        subsample_views: false,
        targets: 1,
        gaussian_stride: 4,
        volume: None,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let draws = 24;
    let wide = (0..draws)
        .filter(|_| {
            let sample = mix.sample(&mut rng, &sample_cfg, &Device::Cpu).unwrap();
            let (l, r) = (&sample.cameras[0], &sample.cameras[1]);
            (l.position - r.position).length() > 0.25
        })
        .count();
    assert!(
        (6..=18).contains(&wide),
        "{wide} of {draws} samples from the 50 cm room"
    );
    // A root too short for its bins, and no root at all, are clear errors.
    let err = open(&[root(SceneKind::Desk, 0.02), root(SceneKind::Room, 1e3)])
        .err()
        .unwrap();
    assert!(matches!(err, DataError::NoBins { .. }), "{err}");
    assert!(err.to_string().contains("room"), "{err}");
    assert!(matches!(open(&[]).err().unwrap(), DataError::NoRoots));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn extremes_give_finite_output_or_clear_errors() {
    // A table 0.1 m from the camera.
    let near = sequence(SynthConfig {
        view_distance_m: Some(0.1),
        ..config(SceneKind::Desk, 2, (160, 120), rig(0.05))
    });
    let f = near.frame(0);
    assert_finite(&f);
    let centre = f.left_depth.data[60 * 160 + 80];
    let nearest = f.left_depth.data.iter().copied().fold(f32::MAX, f32::min);
    eprintln!("0.1 m desk: centre {centre:.3} m, nearest {nearest:.3} m");
    assert!(
        centre > 0.03 && centre < 0.15 && nearest > 0.0,
        "{centre} {nearest}"
    );

    // Baselines of 1 mm and 2 m: the right camera sees the same scene shifted.
    for b in [0.001, 2.0] {
        let seq = sequence(config(SceneKind::Room, 3, (160, 120), rig(b)));
        let f = seq.frame(0);
        assert_finite(&f);
        let mean_diff: f32 = f
            .frame
            .left
            .data
            .iter()
            .zip(&f.frame.right.data)
            .map(|(l, r)| (l - r).abs())
            .sum::<f32>()
            / f.frame.left.data.len() as f32;
        eprintln!("baseline {b} m: mean |left - right| {mean_diff:.4}");
        assert!(
            if b < 0.01 {
                mean_diff < 0.02
            } else {
                mean_diff > 0.02
            },
            "{mean_diff}"
        );
    }

    // Flat (black) and saturated pairs.
    for (exposure, value) in [(0.0, 0.0f32), (1e6, 1.0)] {
        let seq = sequence(SynthConfig {
            exposure,
            ..config(SceneKind::Desk, 4, (96, 72), None)
        });
        let f = seq.frame(0);
        assert_finite(&f);
        let equal = f.frame.left.data.iter().filter(|&&v| v == value).count();
        assert!(
            equal as f64 > 0.99 * f.frame.left.data.len() as f64,
            "exposure {exposure}"
        );
    }

    // What no camera has is refused with the reason.
    let dir = std::env::temp_dir().join(format!("stereosplat-bad-{}", std::process::id()));
    let bad = [
        (rig(0.0), None, 1.0, SynthConfigError::Baseline(0.0)),
        (rig(-0.1), None, 1.0, SynthConfigError::Baseline(-0.1)),
        (rig(20.0), None, 1.0, SynthConfigError::Baseline(20.0)),
        (
            Some(RigChoice {
                hfov_deg: 180.0,
                baseline_m: 0.1,
            }),
            None,
            1.0,
            SynthConfigError::FieldOfView(180.0),
        ),
        (None, Some(0.0), 1.0, SynthConfigError::Distance(0.0)),
        (None, None, -1.0, SynthConfigError::Exposure(-1.0)),
    ];
    for (rig, distance, exposure, expected) in bad {
        let cfg = SynthConfig {
            view_distance_m: distance,
            exposure,
            ..config(SceneKind::Desk, 0, (64, 48), rig)
        };
        assert_eq!(cfg.validate(), Err(expected.clone()));
        match write_synthetic(&dir, &cfg, &mut |_, _| {}) {
            Err(GenerateError::Config(e)) => assert_eq!(e, expected),
            other => panic!("{other:?}"),
        }
    }
    let nan = SynthConfig {
        rig: rig(f64::NAN),
        ..config(SceneKind::Desk, 0, (64, 48), None)
    };
    assert!(matches!(nan.validate(), Err(SynthConfigError::Baseline(b)) if b.is_nan()));
    let empty = config(SceneKind::Room, 0, (0, 48), None);
    assert_eq!(
        empty.validate(),
        Err(SynthConfigError::Size {
            width: 0,
            height: 48
        })
    );
    assert!(!dir.exists(), "nothing written for a refused configuration");
}
