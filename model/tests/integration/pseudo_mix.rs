//! Pseudo-view mixed training: with `pseudo_mix = 1` every input pair after the first is
//! replaced by renders of the network's own prediction from the first pair (finite, in
//! [0, 1], different from the true images, the first pair untouched); with 0, or one pair,
//! nothing changes and no random number is drawn; a training step on a mixed sample has a
//! finite loss and finite gradients.

use crate::drive_support;
use crate::finite_support;

use std::path::PathBuf;

use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use finite_support::assert_finite_gradients;
use model::lpips::{default_weights, Lpips};
use model::net::{Config, StereoSplat};
use model::synth::SynthConfig;
use model::train::{
    losses, mix_pseudo_pairs, DataRoot, LossWeights, Sample, SampleConfig, TrainingSet,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::RenderSettings;

/// A short generated drive (136x40), written once per test process.
fn drive() -> PathBuf {
    let config = SynthConfig {
        seed: 23,
        frames: 24,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    };
    drive_support::once("pseudo-mix", &config).0
}

/// A sample with exactly `pairs` input pairs.
fn sample(pairs: usize) -> Sample {
    let data = TrainingSet::open(&[DataRoot::new(drive())], None).unwrap();
    let cfg = SampleConfig {
        max_pairs: pairs,
        subsample_views: pairs > 1,
        targets: 2,
        gaussian_stride: 2,
        volume: None,
    };
    (0..)
        .map(|s| {
            data.sample(&mut ChaCha8Rng::seed_from_u64(s), &cfg, &Device::Cpu)
                .unwrap()
        })
        .find(|s| s.cameras.len() == 2 * pairs)
        .unwrap()
}

fn network() -> (VarMap, StereoSplat) {
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
    let net = StereoSplat::new(vb, &Config::tiny()).unwrap();
    (varmap, net)
}

fn max_diff(a: &Tensor, b: &Tensor) -> f32 {
    (a - b)
        .unwrap()
        .abs()
        .unwrap()
        .max_all()
        .unwrap()
        .to_scalar()
        .unwrap()
}

#[test]
fn mixing_replaces_later_pairs_by_renders_and_trains_finitely() {
    let (varmap, net) = network();
    let truth = sample(3);
    let mut mixed = sample(3);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    assert_eq!(
        mix_pseudo_pairs(&net, &mut mixed, 1.0, &mut rng).unwrap(),
        2
    );
    assert_eq!(mixed.images.dims(), truth.images.dims());
    assert_eq!(
        max_diff(
            &mixed.images.narrow(0, 0, 2).unwrap(),
            &truth.images.narrow(0, 0, 2).unwrap()
        ),
        0.0
    );
    let later = mixed.images.narrow(0, 2, 4).unwrap();
    assert!(max_diff(&later, &truth.images.narrow(0, 2, 4).unwrap()) > 0.05);
    let values = later.flatten_all().unwrap().to_vec1::<f32>().unwrap();
    assert!(values
        .iter()
        .all(|v| v.is_finite() && (0.0..=1.0).contains(v)));

    let prediction = net.forward(&mixed.images, &mixed.cameras).unwrap();
    let lpips = Lpips::load(default_weights(), DType::F32, &Device::Cpu).unwrap();
    let l = losses(
        &prediction,
        &mixed,
        &lpips,
        &LossWeights::default(),
        &RenderSettings::default(),
        net.config(),
    )
    .unwrap();
    assert!(l.total.to_scalar::<f32>().unwrap().is_finite());
    let grads = l.total.backward().unwrap();
    assert_finite_gradients(&varmap, &grads, "pseudo-mixed step");
}

#[test]
fn without_mixing_or_with_one_pair_nothing_changes_and_nothing_is_drawn() {
    let (_, net) = network();
    for (pairs, p) in [(3, 0.0), (1, 1.0)] {
        let truth = sample(pairs);
        let mut same = sample(pairs);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        assert_eq!(mix_pseudo_pairs(&net, &mut same, p, &mut rng).unwrap(), 0);
        assert_eq!(max_diff(&same.images, &truth.images), 0.0);
        // The generator is where a fresh one of the same seed is.
        let next: u64 = rng.random();
        assert_eq!(next, ChaCha8Rng::seed_from_u64(9).random::<u64>());
    }
}
