//! Shipped weights scored on a generated drive they never trained on: the drive at the
//! training resolution and the evaluation protocol's table over sliding bins.

use std::path::{Path, PathBuf};

use model::bins::{BinConfig, BinLayout};
use model::eval::{evaluate, EvalConfig, Raster, Summary};
use model::generate::write_synthetic;
use model::kitti360::Sequence;
use model::net::{Config, LearnedReconstructor};
use model::synth::SynthConfig;

/// A `frames`-frame drive of `seed` at the training resolution (272x72) under a temp folder
/// named after `tag`: its root (remove it when done) and the sequence.
pub fn drive(tag: &str, seed: u64, frames: u32) -> (PathBuf, Sequence) {
    let root = std::env::temp_dir().join(format!("stereosplat-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let config = SynthConfig {
        seed,
        frames,
        width: 272,
        height: 72,
        ..SynthConfig::default()
    };
    let name = write_synthetic(&root, &config, &mut |_, _| {}).unwrap();
    let sequence = Sequence::open(&root, &name).unwrap();
    (root, sequence)
}

/// The table of `cfg` with `weights` over bins starting every `stride` frames, `pairs` input
/// pairs per bin, at least `min_bins` of them and none skipped; the network is returned for
/// its last report.
pub fn score(
    sequence: &Sequence,
    cfg: &Config,
    weights: &Path,
    stride: usize,
    pairs: usize,
    min_bins: usize,
) -> (Summary, LearnedReconstructor) {
    let mut net = LearnedReconstructor::load(cfg, weights).unwrap();
    let config = EvalConfig {
        bins: BinConfig {
            layout: BinLayout::Sliding { stride },
            ..BinConfig::default()
        },
        input_pairs: pairs,
        ..EvalConfig::default()
    };
    let (bins, skipped) = evaluate(
        sequence,
        &mut net,
        &mut Raster::Cpu,
        &config,
        &mut |_, _| {},
    )
    .unwrap();
    assert!(skipped.is_empty(), "{skipped:?}");
    assert!(bins.len() >= min_bins, "{} bins", bins.len());
    (Summary::of(&bins), net)
}
