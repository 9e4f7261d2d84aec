//! `train-enhancer`: the enhancer trained on pairs from `enhancer-data`, the way StereoSplat
//! trains (`crate::train`): seeded initialisation and batches (batch `s` drawn from a
//! generator seeded by the run's seed and `s`, so a resumed run draws what it would have),
//! AdamW whose moments are checkpointed, linear warm-up then a constant rate, global
//! gradient clipping, `log.csv` and `loss_curve.png`, and the weights exported as
//! `enhancer_<preset>.safetensors` at every checkpoint (the checkpoint code is
//! StereoSplat's, `train::checkpoint`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use candle_core::{DType, Device};
use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::loss::{losses, LossWeights};
use super::pairs::PairSet;
use super::{Config, EnhanceError, Enhancer};
use crate::lpips::{default_weights, Lpips};
use crate::net::load_matching;
use crate::train::checkpoint::Run;
use crate::train::{mix, AdamWConfig, TrainError};

/// The log's columns: `raw_l2` is the L2 of the render itself (what the identity scores).
pub const LOG_COLUMNS: &[&str] = &[
    "step",
    "loss",
    "l2",
    "lpips",
    "style",
    "raw_l2",
    "lr",
    "grad_norm",
    "steps_per_s",
    "elapsed_s",
];

/// The columns drawn in `loss_curve.png`.
pub const CURVE_COLUMNS: &[&str] = &["loss", "l2", "lpips", "style", "raw_l2"];

/// Settings of a run.
#[derive(Clone, Debug)]
pub struct TrainConfig {
    /// Optimizer steps in all.
    pub steps: u64,
    /// Pairs per step.
    pub batch: usize,
    /// Learning rate after warm-up.
    pub lr: f64,
    /// Steps of linear warm-up.
    pub warmup: u64,
    /// Largest global gradient norm.
    pub clip: f64,
    /// Seed of the weights and batches.
    pub seed: u64,
    /// Steps between checkpoints.
    pub checkpoint_every: u64,
    /// Loss weights.
    pub loss: LossWeights,
    /// Optimizer settings.
    pub adamw: AdamWConfig,
}

/// What one step did.
#[derive(Clone, Debug)]
pub struct StepReport {
    /// The step just taken (1-based).
    pub step: u64,
    /// Total loss.
    pub loss: f32,
    /// L2 of the enhanced render.
    pub l2: f32,
    /// LPIPS of the enhanced render.
    pub lpips: f32,
    /// Gram distance of the enhanced render.
    pub style: f32,
    /// L2 of the raw render.
    pub raw_l2: f32,
    /// Learning rate used.
    pub lr: f64,
    /// Gradient norm before clipping.
    pub grad_norm: f64,
    /// Steps per second in this session.
    pub steps_per_s: f64,
    /// Seconds of training in all sessions.
    pub elapsed_s: f64,
}

/// The checkpoint's bookkeeping (`state.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
struct State {
    config: Config,
    step: u64,
    seed: u64,
    elapsed_s: f64,
}

/// The exported weights of a run: `<out>/enhancer_<preset>.safetensors`.
pub fn exported_weights(out: &Path, preset: &str) -> PathBuf {
    out.join(format!("enhancer_{preset}.safetensors"))
}

/// A training run in progress.
pub struct Trainer {
    run: Run,
    net: Enhancer,
    lpips: Lpips,
    pairs: PairSet,
    cfg: TrainConfig,
}

impl Trainer {
    /// A run of `net_cfg` on the pairs in `pairs`, writing to `out`; with `resume`,
    /// continues from `out`'s checkpoint (refused if it is of other sizes).
    pub fn new(
        net_cfg: &Config,
        cfg: TrainConfig,
        pairs: &Path,
        out: &Path,
        resume: bool,
    ) -> Result<Self, EnhanceError> {
        let set = PairSet::open(pairs)?;
        if set.is_empty() {
            return Err(EnhanceError::NoPairs(pairs.to_path_buf()));
        }
        let check = |state: State| {
            if state.config != *net_cfg {
                let json = |c: &Config| serde_json::to_string(c).expect("config serialises");
                return Err(TrainError::SettingsMismatch {
                    preset: format!("enhancer {}", net_cfg.name),
                    expected: json(net_cfg),
                    found: json(&state.config),
                });
            }
            Ok((state.step, state.elapsed_s))
        };
        let (run, net) = Run::start(
            out,
            &Device::Cpu,
            cfg.seed,
            cfg.adamw.clone(),
            LOG_COLUMNS,
            resume,
            |vb| Enhancer::new(vb, net_cfg),
            check,
        )?;
        Ok(Self {
            lpips: Lpips::load(default_weights(), DType::F32, &Device::Cpu)?,
            run,
            net,
            pairs: set,
            cfg,
        })
    }

    /// Starts from the enhancer weights in the safetensors file at `path` instead of the
    /// seeded initialisation (fine-tuning on new pairs); every tensor must match the
    /// preset's shapes, and a weight the file lacks is an error, so no layer starts fresh
    /// unnoticed.
    pub fn load_weights(&mut self, path: &Path) -> Result<usize, EnhanceError> {
        let warm = load_matching(&self.run.varmap, path)?;
        if !warm.fresh.is_empty() {
            return Err(EnhanceError::InitIncomplete {
                path: path.to_path_buf(),
                missing: warm.fresh.join(", "),
            });
        }
        Ok(warm.loaded)
    }

    /// Steps already taken.
    pub fn step(&self) -> u64 {
        self.run.optimizer.step
    }

    /// Training pairs.
    pub fn pairs(&self) -> usize {
        self.pairs.len()
    }

    /// Number of weights.
    pub fn parameters(&self) -> usize {
        self.run
            .varmap
            .all_vars()
            .iter()
            .map(|v| v.elem_count())
            .sum()
    }

    /// Trains until the configured step count or until `stop` returns true, reporting every
    /// step; checkpoints every `checkpoint_every` steps and at the end.
    pub fn run(
        &mut self,
        stop: &dyn Fn() -> bool,
        report: &mut dyn FnMut(&StepReport),
    ) -> Result<(), EnhanceError> {
        let start = Instant::now();
        let first = self.run.optimizer.step;
        while self.run.optimizer.step < self.cfg.steps && !stop() {
            let step = self.run.optimizer.step + 1;
            let mut rng = ChaCha8Rng::seed_from_u64(mix(self.cfg.seed, step));
            let n = self.pairs.len();
            let picked = sample(&mut rng, n, self.cfg.batch.clamp(1, n)).into_vec();
            let batch = self
                .pairs
                .batch(&picked, rng.random_bool(0.5), &Device::Cpu)?;
            let output = self.net.forward(&batch.render, &batch.reference)?;
            let l = losses(&output, &batch.target, &self.lpips, &self.cfg.loss)?;
            let raw_l2 = (batch.render.narrow(1, 0, 3)? - &batch.target)?
                .sqr()?
                .mean_all()?
                .to_scalar::<f32>()?;
            let (lr, grad_norm) =
                self.run
                    .learn(&l.total, self.cfg.lr, self.cfg.warmup, self.cfg.clip, step)?;
            let session = start.elapsed().as_secs_f64();
            let r = StepReport {
                step,
                loss: l.total.to_scalar::<f32>()?,
                l2: l.l2,
                lpips: l.lpips,
                style: l.style,
                raw_l2,
                lr,
                grad_norm,
                steps_per_s: (step - first) as f64 / session.max(1e-9),
                elapsed_s: self.run.elapsed_before + session,
            };
            let row = format!(
                "{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.3e},{:.4},{:.4},{:.1}",
                r.step,
                r.loss,
                r.l2,
                r.lpips,
                r.style,
                r.raw_l2,
                r.lr,
                r.grad_norm,
                r.steps_per_s,
                r.elapsed_s
            );
            self.run.log_row(&row)?;
            report(&r);
            if step.is_multiple_of(self.cfg.checkpoint_every) {
                self.checkpoint(r.elapsed_s)?;
            }
        }
        self.checkpoint(self.run.elapsed_before + start.elapsed().as_secs_f64())
    }

    fn checkpoint(&self, elapsed_s: f64) -> Result<(), EnhanceError> {
        let cfg = self.net.config();
        let state = State {
            config: cfg.clone(),
            step: self.run.optimizer.step,
            seed: self.cfg.seed,
            elapsed_s,
        };
        let export = exported_weights(&self.run.out, &cfg.name);
        Ok(self.run.save(&state, &export, CURVE_COLUMNS)?)
    }
}
