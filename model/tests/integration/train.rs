//! Training end to end on a small generated drive: steps run and are logged, checkpoints
//! resume exactly (a run stopped at step 4 and resumed to 6 ends with the weights of a run
//! that went straight to 6), the loss curve is drawn, a checkpoint of another preset is
//! refused, and the matching loss adds exactly its weighted cross-entropy and is logged.

use std::path::{Path, PathBuf};

use model::net::Config;
use model::synth::SynthConfig;
use model::train::{
    exported_weights, AdamWConfig, DataRoot, LossWeights, SampleConfig, TrainConfig, TrainError,
    Trainer,
};

use crate::drive_support;
use crate::train_support;
use train_support::{assert_same_weights, logged_steps};

/// The small generated drive both tests train on, written once per test process.
fn drive() -> PathBuf {
    let config = SynthConfig {
        seed: 11,
        frames: 40,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    };
    drive_support::once("train", &config).0
}

fn temp(case: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereosplat-train-{case}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn train_config(steps: u64) -> TrainConfig {
    TrainConfig {
        steps,
        lr: 1e-3,
        warmup: 2,
        clip: 1.0,
        seed: 3,
        checkpoint_every: 2,
        sample: SampleConfig {
            max_pairs: 2,
            subsample_views: true,
            targets: 1,
            gaussian_stride: Config::tiny().gaussian_stride,
            volume: None,
        },
        loss: LossWeights::default(),
        adamw: AdamWConfig::default(),
        resize: None,
    }
}

fn run(data: &Path, out: &Path, steps: u64, resume: bool) -> Vec<f32> {
    let mut trainer = Trainer::new(
        &Config::tiny(),
        train_config(steps),
        &[DataRoot::new(data)],
        out,
        resume,
    )
    .unwrap();
    let mut losses = Vec::new();
    trainer
        .run(&|| false, &mut |r| {
            assert!(r.loss.is_finite() && r.grad_norm.is_finite());
            losses.push(r.loss);
        })
        .unwrap();
    assert_eq!(trainer.step(), steps);
    losses
}

#[test]
fn a_resumed_run_ends_where_a_straight_run_does() {
    let data = drive();

    let (resumed, straight) = (temp("resumed"), temp("straight"));
    let first = run(&data, &resumed, 4, false);
    let second = run(&data, &resumed, 6, true);
    assert_eq!((first.len(), second.len()), (4, 2));
    let all = run(&data, &straight, 6, false);
    assert_eq!(&all[..4], &first[..], "same seed, same first steps");
    for (a, b) in all[4..].iter().zip(&second) {
        assert!((a - b).abs() <= 1e-5 * a.abs().max(1.0), "{a} vs {b}");
    }
    assert_same_weights(
        &exported_weights(&resumed, "tiny"),
        &exported_weights(&straight, "tiny"),
    );
    assert_eq!(logged_steps(&resumed), ["1", "2", "3", "4", "5", "6"]);
    let curve = image::open(resumed.join("loss_curve.png")).unwrap();
    assert_eq!((curve.width(), curve.height()), (800, 480));

    let roots = [DataRoot::new(&data)];
    let small = Trainer::new(&Config::small(), train_config(8), &roots, &resumed, true);
    assert!(matches!(small, Err(TrainError::PresetMismatch { .. })));
    // Network settings must match on resume; settings that only prune at inference need not.
    let unbounded = Config::tiny()
        .with_settings(&["depth_logit_bound=null"])
        .unwrap();
    let other = Trainer::new(&unbounded, train_config(8), &roots, &resumed, true);
    assert!(matches!(other, Err(TrainError::SettingsMismatch { .. })));
    let pruning = Config::tiny().with_settings(&["pair_fusion_margin=null", "opacity_floor=0.1"]);
    assert!(Trainer::new(&pruning.unwrap(), train_config(8), &roots, &resumed, true).is_ok());
    for dir in [resumed, straight] {
        let _ = std::fs::remove_dir_all(dir);
    }
}

#[test]
fn the_matching_loss_adds_its_weighted_cross_entropy_and_is_logged() {
    let data = drive();
    // One step each, same seed: the same sample and the same untrained network.
    let first_step = |weight: f64, out: &Path| {
        let mut cfg = train_config(1);
        cfg.loss.matching = weight;
        let mut trainer =
            Trainer::new(&Config::tiny(), cfg, &[DataRoot::new(&data)], out, false).unwrap();
        let mut report = None;
        trainer
            .run(&|| false, &mut |r| report = Some((r.loss, r.matching)))
            .unwrap();
        report.unwrap()
    };
    let (off, on) = (temp("matching-off"), temp("matching-on"));
    let (base, none) = first_step(0.0, &off);
    let (total, matching) = first_step(0.5, &on);
    assert_eq!(none, 0.0);
    // A cross-entropy over 32 candidates: positive, finite, near ln 32 for a fresh network.
    assert!(matching > 0.5 && matching < 10.0, "{matching}");
    let added = total - base;
    assert!(
        (added - 0.5 * matching).abs() < 1e-4,
        "{added} vs {}",
        0.5 * matching
    );
    let log = std::fs::read_to_string(on.join("log.csv")).unwrap();
    let mut lines = log.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let row: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = header.iter().position(|c| *c == "matching").unwrap();
    let logged: f32 = row[column].parse().unwrap();
    assert!((logged - matching).abs() < 1e-3, "{logged} vs {matching}");
    for dir in [off, on] {
        let _ = std::fs::remove_dir_all(dir);
    }
}
