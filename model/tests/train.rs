//! Training end to end on a small generated drive: steps run and are logged, checkpoints
//! resume exactly (a run stopped at step 4 and resumed to 6 ends with the weights of a run
//! that went straight to 6), the loss curve is drawn, and a checkpoint of another preset is
//! refused.

use std::path::{Path, PathBuf};

use model::bins::BinConfig;
use model::generate::write_synthetic;
use model::net::Config;
use model::synth::SynthConfig;
use model::train::{
    exported_weights, AdamWConfig, LossWeights, SampleConfig, TrainConfig, TrainError, Trainer,
};

mod train_support;
use train_support::{assert_same_weights, logged_steps};

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
        bins: BinConfig::default(),
        adamw: AdamWConfig::default(),
        resize: None,
    }
}

fn run(data: &Path, out: &Path, steps: u64, resume: bool) -> Vec<f32> {
    let mut trainer =
        Trainer::new(&Config::tiny(), train_config(steps), data, out, resume).unwrap();
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
    let data = temp("data");
    let config = SynthConfig {
        seed: 11,
        frames: 40,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    };
    write_synthetic(&data, &config, &mut |_, _| {}).unwrap();

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

    let small = Trainer::new(&Config::small(), train_config(8), &data, &resumed, true);
    assert!(matches!(small, Err(TrainError::PresetMismatch { .. })));
    // Network settings must match on resume; settings that only prune at inference need not.
    let unbounded = Config::tiny()
        .with_settings(&["depth_logit_bound=null"])
        .unwrap();
    let other = Trainer::new(&unbounded, train_config(8), &data, &resumed, true);
    assert!(matches!(other, Err(TrainError::SettingsMismatch { .. })));
    let pruning = Config::tiny().with_settings(&["pair_fusion_margin=null", "opacity_floor=0.1"]);
    assert!(Trainer::new(&pruning.unwrap(), train_config(8), &data, &resumed, true).is_ok());
    for dir in [data, resumed, straight] {
        let _ = std::fs::remove_dir_all(dir);
    }
}
