//! Training of the StereoSplat network (paper section 3.2.4-3.2.5 and 4.2): samples from bins
//! with stochastic view subsampling, renders of the predicted Gaussians through the
//! differentiable rasterizer, the paper's losses, AdamW with betas (0.9, 0.99), linear
//! warm-up then a constant rate, global gradient clipping, seeded everything, checkpoints
//! with exact resume, a CSV log and the weights exported as safetensors. With the volume
//! branch on, samples carry the bin's occupied voxels and each target's in-volume pixels,
//! and the branch's two losses join the objective (see `loss`); a run can start from a
//! weight file that holds only part of the network (`load_weights`: the shipped cost-volume
//! weights, the volume branch fresh); `interpolate` blends two trained end points in weight
//! space.

mod adamw;
pub(crate) mod checkpoint;
mod data;
mod interpolate;
mod log;
mod loss;
mod matching;
mod pseudo_mix;

use std::path::{Path, PathBuf};
use std::time::Instant;

use candle_core::{DType, Tensor};
use candle_nn::VarMap;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use adamw::{AdamW, AdamWConfig};
pub use checkpoint::checkpoint_dir;
pub use data::{
    depth_tensor, image_tensor, DataError, DataRoot, Sample, SampleConfig, Target, TrainingSet,
};
pub(crate) use data::{draw_targets, BinInputs};
pub use interpolate::{interpolate, interpolate_files, InterpolateError};
pub use log::{TrainLog, LOG_COLUMNS};
pub use loss::{depth_loss, losses, masked_l1, DepthError, LossWeights, Losses, UnknownDepthError};
pub use matching::matching_loss;
pub use pseudo_mix::mix_pseudo_pairs;

use crate::compute::ComputeDevice;
use crate::lpips::{default_weights, Lpips};
use crate::net::volume::VolumeConfig;
use crate::net::{load_matching, Config, StereoSplat, WarmStart};
use renderer::RenderSettings;

/// The log columns drawn in `loss_curve.png`.
pub const CURVE_COLUMNS: &[&str] = &["loss", "l2", "lpips", "estimated_depth", "rendered_depth"];

/// Why training stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// Training data could not be read.
    #[error(transparent)]
    Data(#[from] DataError),
    /// A tensor operation failed.
    #[error(transparent)]
    Tensor(#[from] candle_core::Error),
    /// A file of the run could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// The checkpoint belongs to another preset.
    #[error("checkpoint is for preset `{found}`, not `{expected}`")]
    PresetMismatch {
        /// The preset asked for.
        expected: String,
        /// The checkpoint's.
        found: String,
    },
    /// The checkpoint was trained with other network settings (`--set` differs).
    #[error("checkpoint was trained with other settings of preset `{preset}`: {found} (asked: {expected})")]
    SettingsMismatch {
        /// The preset.
        preset: String,
        /// The settings asked for, as JSON.
        expected: String,
        /// The checkpoint's, as JSON.
        found: String,
    },
    /// The loss curve could not be drawn.
    #[error(transparent)]
    Curve(#[from] crate::curve::CurveError),
    /// The checkpoint state file is not valid JSON.
    #[error("checkpoint state {0}: {1}")]
    State(PathBuf, serde_json::Error),
}

/// Settings of a training run.
#[derive(Clone, Debug)]
pub struct TrainConfig {
    /// Optimizer steps in all (a resumed run stops at the same total).
    pub steps: u64,
    /// Learning rate after warm-up.
    pub lr: f64,
    /// Steps of linear warm-up.
    pub warmup: u64,
    /// Largest global gradient norm.
    pub clip: f64,
    /// Seed of the initial weights and of every sample.
    pub seed: u64,
    /// Steps between checkpoints.
    pub checkpoint_every: u64,
    /// How samples are drawn.
    pub sample: SampleConfig,
    /// Loss weights.
    pub loss: LossWeights,
    /// Optimizer settings.
    pub adamw: AdamWConfig,
    /// Read the frames at this size (width, height; intrinsics scaled), e.g. real KITTI-360
    /// at 544x144; `None`: as stored.
    pub resize: Option<(u32, u32)>,
}

/// What one step did, for progress and the log.
#[derive(Clone, Debug)]
pub struct StepReport {
    /// The step just taken (1-based).
    pub step: u64,
    /// Total loss.
    pub loss: f32,
    /// Image L2.
    pub l2: f32,
    /// LPIPS.
    pub lpips: f32,
    /// Rendered-depth error (metres, or a fraction with the relative depth loss).
    pub rendered_depth: f32,
    /// Estimated-depth error (metres, or a fraction with the relative depth loss).
    pub estimated_depth: f32,
    /// Confidence regression error.
    pub confidence: f32,
    /// Occupancy cross-entropy of the volume branch (0 without it).
    pub occupancy: f32,
    /// Masked L2 of the volume-only render (0 without the branch).
    pub volume_l2: f32,
    /// Gaussians the volume branch decoded (0 without it).
    pub volume_gaussians: usize,
    /// Matching cross-entropy of the cost volume (0 when its weight is 0).
    pub matching: f32,
    /// Learning rate used.
    pub lr: f64,
    /// Gradient norm before clipping.
    pub grad_norm: f64,
    /// Input pairs of the sample.
    pub pairs: usize,
    /// Steps per second over this session's steps.
    pub steps_per_s: f64,
    /// Seconds of training in all sessions.
    pub elapsed_s: f64,
}

/// The checkpoint's bookkeeping (`state.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
struct State {
    preset: String,
    /// The network's settings (absent in checkpoints from before settings could change).
    #[serde(default)]
    config: Option<Config>,
    step: u64,
    seed: u64,
    elapsed_s: f64,
}

/// Whether two presets build the same network and train it alike: the settings of inference
/// alone (opacity floor, budget, pair fusion, joint pairs, merging, pruning, SGM's snap,
/// the progressive pass) do not count, nor the fill of SGM's hints (it changes what the
/// hints hold, not the network), nor the schedule-like view subsampling and pseudo-view mixing (a run
/// may change them when it resumes), nor the device it runs on, nor the volume branch's sizes while the branch is off (checkpoints from before the branch
/// existed read them as `tiny`'s).
fn same_network(a: &Config, b: &Config) -> bool {
    let training = |c: &Config| Config {
        opacity_floor: 0.0,
        max_gaussians: 0,
        pair_fusion_margin: None,
        merge_tolerance: None,
        min_view_weight: None,
        sgm_snap: false,
        sgm_fill: false,
        joint_pairs: false,
        view_subsampling: true,
        volume_fusion_margin: None,
        volume_branch_far_only: false,
        progressive: false,
        progressive_every: 1,
        enhancer: true,
        enhancer_weights: None,
        pseudo_poses: Vec::new(),
        pseudo_fusion_margin: 0.0,
        pseudo_confidence_power: 0.0,
        pseudo_mix: 0.0,
        device: ComputeDevice::Cpu,
        volume: match c.volume_branch {
            true => c.volume.clone(),
            false => VolumeConfig::default(),
        },
        ..c.clone()
    };
    training(a) == training(b)
}

/// The exported weights of a run: `<out>/stereosplat_<preset>.safetensors`.
pub fn exported_weights(out: &Path, preset: &str) -> PathBuf {
    out.join(format!("stereosplat_{preset}.safetensors"))
}

/// A training run in progress.
pub struct Trainer {
    run: checkpoint::Run,
    net: StereoSplat,
    lpips: Lpips,
    data: TrainingSet,
    cfg: TrainConfig,
}

impl Trainer {
    /// A run of preset `net_cfg` on the sequences under the `data` roots, writing to `out`; with
    /// `resume`, continues from `out`'s checkpoint (weights, optimizer moments, step, log).
    pub fn new(
        net_cfg: &Config,
        mut cfg: TrainConfig,
        data: &[DataRoot],
        out: &Path,
        resume: bool,
    ) -> Result<Self, TrainError> {
        // `sgm_snap` is an inference setting: training takes the network's own depth
        // everywhere.
        let net_cfg = &Config {
            sgm_snap: false,
            ..net_cfg.clone()
        };
        cfg.sample.volume = net_cfg.volume_branch.then(|| net_cfg.volume.clone());
        let check = |state: State| {
            if state.preset != net_cfg.name {
                return Err(TrainError::PresetMismatch {
                    expected: net_cfg.name.clone(),
                    found: state.preset,
                });
            }
            if let Some(found) = state.config.filter(|c| !same_network(c, net_cfg)) {
                let json = |c: &Config| serde_json::to_string(c).expect("config serialises");
                return Err(TrainError::SettingsMismatch {
                    preset: net_cfg.name.clone(),
                    expected: json(net_cfg),
                    found: json(&found),
                });
            }
            Ok((state.step, state.elapsed_s))
        };
        let device = net_cfg.device.open()?;
        let (run, net) = checkpoint::Run::start(
            out,
            &device,
            cfg.seed,
            cfg.adamw.clone(),
            LOG_COLUMNS,
            resume,
            |vb| StereoSplat::new(vb, net_cfg),
            check,
        )?;
        Ok(Self {
            lpips: Lpips::load(default_weights(), DType::F32, &device)?,
            data: TrainingSet::open(data, cfg.resize)?,
            run,
            net,
            cfg,
        })
    }

    /// Replaces the weights with those a safetensors file holds (the start of a fine-tuning
    /// run, or a warm start: the shipped cost-volume weights under a network with the volume
    /// branch). Variables the file lacks keep their seeded values and are named in the
    /// report; a tensor of another shape is an error.
    pub fn load_weights(&mut self, path: &Path) -> Result<WarmStart, TrainError> {
        Ok(load_matching(&self.run.varmap, path)?)
    }

    /// Steps already taken.
    pub fn step(&self) -> u64 {
        self.run.optimizer.step
    }

    /// Bins in the training set.
    pub fn bins(&self) -> usize {
        self.data.len()
    }

    /// Trains until the configured step count or until `stop` returns true, reporting
    /// every step; checkpoints every `checkpoint_every` steps and at the end.
    pub fn run(
        &mut self,
        stop: &dyn Fn() -> bool,
        report: &mut dyn FnMut(&StepReport),
    ) -> Result<(), TrainError> {
        let start = Instant::now();
        let first = self.run.optimizer.step;
        let settings = RenderSettings::default();
        while self.run.optimizer.step < self.cfg.steps && !stop() {
            let step = self.run.optimizer.step + 1;
            let mut rng = ChaCha8Rng::seed_from_u64(mix(self.cfg.seed, step));
            let device = self.net.device();
            let mut sample = self.data.sample(&mut rng, &self.cfg.sample, &device)?;
            mix_pseudo_pairs(
                &self.net,
                &mut sample,
                self.net.config().pseudo_mix,
                &mut rng,
            )?;
            // With `auto_depth_range` the candidates span the sample's own scene, as they
            // will at inference, so the network learns them relative to that range; with
            // `sgm_guidance` the sample's SGM hints join the logits, as at inference.
            // With `rig_disparity_fraction` they follow the sample's rig first.
            let rigged = self.net.for_rig(&sample.cameras);
            let ranged = rigged
                .fitted_to_scene(&sample.images, &sample.cameras)
                .map(|(net, _)| net);
            let net = ranged.as_ref().unwrap_or(&rigged);
            let prediction = net.forward(&sample.images, &sample.cameras)?;
            let l = losses(
                &prediction,
                &sample,
                &self.lpips,
                &self.cfg.loss,
                &settings,
                net.config(),
            )?;
            let (lr, grad_norm) =
                self.run
                    .learn(&l.total, self.cfg.lr, self.cfg.warmup, self.cfg.clip, step)?;
            let session = start.elapsed().as_secs_f64();
            let r = StepReport {
                step,
                loss: l.total.to_scalar::<f32>()?,
                l2: l.l2,
                lpips: l.lpips,
                rendered_depth: l.rendered_depth,
                estimated_depth: l.estimated_depth,
                confidence: l.confidence,
                occupancy: l.occupancy,
                volume_l2: l.volume_l2,
                matching: l.matching,
                volume_gaussians: prediction.volume.as_ref().map_or(0, |v| v.gaussians()),
                lr,
                grad_norm,
                pairs: sample.cameras.len() / 2,
                steps_per_s: (step - first) as f64 / session.max(1e-9),
                elapsed_s: self.run.elapsed_before + session,
            };
            self.run
                .log
                .append(&r)
                .map_err(checkpoint::io_error(&self.run.out.join("log.csv")))?;
            report(&r);
            if step.is_multiple_of(self.cfg.checkpoint_every) {
                self.checkpoint(r.elapsed_s)?;
            }
        }
        self.checkpoint(self.run.elapsed_before + start.elapsed().as_secs_f64())
    }

    /// Writes the checkpoint (see [`checkpoint`]) and exports the weights.
    fn checkpoint(&self, elapsed_s: f64) -> Result<(), TrainError> {
        let state = State {
            preset: self.net.config().name.clone(),
            config: Some(self.net.config().clone()),
            step: self.run.optimizer.step,
            seed: self.cfg.seed,
            elapsed_s,
        };
        let export = exported_weights(&self.run.out, &self.net.config().name);
        self.run.save(&state, &export, CURVE_COLUMNS)
    }
}

/// The learning rate at `step`: linear warm-up over `warmup` steps to `lr`, then constant.
pub(crate) fn warmup_lr(lr: f64, warmup: u64, step: u64) -> f64 {
    let warm = warmup.max(1);
    lr * (step.min(warm) as f64 / warm as f64)
}

/// A per-step seed from the run's seed, so a resumed run draws the samples it would have.
pub(crate) fn mix(seed: u64, step: u64) -> u64 {
    seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ step.wrapping_mul(0xD1B5_4A32_D192_ED03)
}

/// Redraws every variable from a generator seeded with `seed` (candle's CPU initialisers
/// cannot be seeded), uniform with the spread of candle-nn's initialisers, which depends only
/// on names and shapes: weights of rank 2 and up with the standard deviation of Kaiming
/// normal (`sqrt(2 / fan_in)`), their biases within `1 / sqrt(fan_in)`, the transformer's
/// position embedding with standard deviation 0.02. Constants (norm weights and biases)
/// stay as they are, and so do variables under a `zero_` name (zero-initialised layers,
/// `ops::Conv::zeros`).
pub(crate) fn reseed(varmap: &VarMap, seed: u64) -> candle_core::Result<()> {
    let data = varmap.data().lock().expect("varmap lock");
    let fan_in = |name: &str| {
        data.get(name)
            .filter(|v| v.rank() >= 2)
            .map(|v| v.dims()[1..].iter().product::<usize>() as f64)
    };
    let mut names: Vec<&String> = data.keys().collect();
    names.sort();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for name in names {
        let var = &data[name];
        let bound = if name.split('.').any(|part| part.starts_with("zero_")) {
            continue;
        } else if name.ends_with("position") {
            0.02 * 3f64.sqrt()
        } else if var.rank() >= 2 {
            (3.0 * 2.0 / fan_in(name).unwrap_or(1.0)).sqrt()
        } else if let Some(f) = name
            .strip_suffix("bias")
            .and_then(|prefix| fan_in(&format!("{prefix}weight")))
        {
            1.0 / f.sqrt()
        } else {
            continue;
        };
        let fresh: Vec<f32> = (0..var.elem_count())
            .map(|_| rng.random_range(-bound..bound) as f32)
            .collect();
        var.set(&Tensor::from_vec(fresh, var.shape(), var.device())?)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inference_settings_and_an_unused_volume_do_not_block_a_resume() {
        let small = Config::small();
        // A checkpoint written before the volume branch existed reads `tiny`'s volume sizes.
        let old = Config {
            volume: VolumeConfig::default(),
            min_view_weight: Some(0.5),
            ..small.clone()
        };
        assert!(same_network(&old, &small));
        // Nor do the progressive pass's settings, inference and training alike.
        let plus = small
            .clone()
            .with_settings(&["progressive=true", "pseudo_mix=0.5", "pseudo_poses=[3.0]"])
            .unwrap();
        assert!(same_network(&plus, &small));
        // With the branch on, its sizes are the network's.
        let on = |c: &Config| Config {
            volume_branch: true,
            ..c.clone()
        };
        assert!(!same_network(&on(&old), &on(&small)));
        assert!(!same_network(&small, &on(&small)));
        assert!(!same_network(&small, &Config::tiny()));
    }
}
