//! A run directory's checkpoint, shared by every trainer of the crate (StereoSplat's and the
//! enhancer's): `checkpoint/weights.safetensors`, `checkpoint/optimizer.safetensors` (AdamW
//! moments) and `checkpoint/state.json` (the trainer's own bookkeeping), written in that
//! order through temporary files so a state file always describes complete files; then the
//! exported weights and the loss curve of `log.csv`. [`Run`] holds what every trainer keeps
//! besides its network and data, and starts or resumes it.

use std::path::{Path, PathBuf};

use candle_core::{DType, Device, Var};
use candle_nn::{VarBuilder, VarMap};
use serde::de::DeserializeOwned;
use serde::Serialize;

use super::{reseed, AdamW, AdamWConfig, TrainError, TrainLog};

/// A run's variables, their optimizer, its directory and log, and the seconds of its
/// earlier sessions.
pub(crate) struct Run {
    /// The network's variables.
    pub varmap: VarMap,
    /// AdamW over them (its `step` is the run's).
    pub optimizer: AdamW,
    /// The run directory.
    pub out: PathBuf,
    /// `log.csv`.
    pub log: TrainLog,
    /// Seconds of training before this session.
    pub elapsed_before: f64,
}

impl Run {
    /// Starts a run in `out` on `device`: `build` makes the network on fresh variables, which are then
    /// drawn from `seed`; with `resume` and a checkpoint there, `check` vets its state and
    /// returns its step and seconds, and the weights and moments are loaded. The log
    /// (`columns`) keeps its rows up to that step.
    // Two trainers share it; each argument is one thing a run needs (no natural grouping).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn start<N, S: DeserializeOwned>(
        out: &Path,
        device: &Device,
        seed: u64,
        adamw: AdamWConfig,
        columns: &[&str],
        resume: bool,
        build: impl FnOnce(VarBuilder) -> candle_core::Result<N>,
        check: impl FnOnce(S) -> Result<(u64, f64), TrainError>,
    ) -> Result<(Self, N), TrainError> {
        std::fs::create_dir_all(checkpoint_dir(out)).map_err(io_error(out))?;
        let varmap = VarMap::new();
        let net = build(VarBuilder::from_varmap(&varmap, DType::F32, device))?;
        reseed(&varmap, seed)?;
        let mut optimizer = AdamW::new(variables(&varmap), adamw)?;
        let state = match resume {
            true => read_state::<S>(out)?,
            false => None,
        };
        let (step, elapsed_before) = match state {
            Some(state) => {
                let (step, elapsed) = check(state)?;
                load(out, &varmap, &mut optimizer, step)?;
                (step, elapsed)
            }
            None => (0, 0.0),
        };
        let path = out.join("log.csv");
        let log = TrainLog::open(&path, columns, step).map_err(io_error(&path))?;
        let run = Self {
            varmap,
            optimizer,
            out: out.to_path_buf(),
            log,
            elapsed_before,
        };
        Ok((run, net))
    }

    /// Backpropagates `loss` and takes optimizer step `step` at `lr` after `warmup` steps of
    /// linear warm-up, gradients clipped to `clip`; returns the rate used and the gradient
    /// norm before clipping.
    pub(crate) fn learn(
        &mut self,
        loss: &candle_core::Tensor,
        lr: f64,
        warmup: u64,
        clip: f64,
        step: u64,
    ) -> Result<(f64, f64), TrainError> {
        let mut grads = loss.backward()?;
        let lr = super::warmup_lr(lr, warmup, step);
        let norm = self.optimizer.clip_and_update(&mut grads, clip, lr)?;
        Ok((lr, norm))
    }

    /// Appends a row to the log.
    pub(crate) fn log_row(&mut self, row: &str) -> Result<(), TrainError> {
        self.log
            .append_row(row)
            .map_err(io_error(&self.out.join("log.csv")))
    }

    /// Writes the checkpoint with `state`, the weights to `export`, and the curve.
    pub(crate) fn save<S: Serialize>(
        &self,
        state: &S,
        export: &Path,
        curve_columns: &[&str],
    ) -> Result<(), TrainError> {
        save(
            &self.out,
            &self.varmap,
            &self.optimizer,
            state,
            export,
            curve_columns,
        )
    }
}

/// The checkpoint folder of a run directory.
pub fn checkpoint_dir(out: &Path) -> PathBuf {
    out.join("checkpoint")
}

/// An I/O error about `path` as a [`TrainError`].
pub(crate) fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> TrainError {
    let path = path.to_path_buf();
    move |source| TrainError::Io { path, source }
}

/// The variables of `varmap` by name (the optimizer's slots).
fn variables(varmap: &VarMap) -> Vec<(String, Var)> {
    varmap
        .data()
        .lock()
        .expect("varmap lock")
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect()
}

/// The state file of `out`'s checkpoint, if there is one.
fn read_state<S: DeserializeOwned>(out: &Path) -> Result<Option<S>, TrainError> {
    let path = checkpoint_dir(out).join("state.json");
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).map_err(io_error(&path))?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| TrainError::State(path, e))
}

/// Loads the checkpoint's weights into `varmap` and its moments into `optimizer` at `step`.
fn load(out: &Path, varmap: &VarMap, optimizer: &mut AdamW, step: u64) -> Result<(), TrainError> {
    let dir = checkpoint_dir(out);
    let mut varmap = varmap.clone();
    varmap.load(dir.join("weights.safetensors"))?;
    optimizer.load(&dir.join("optimizer.safetensors"), step)?;
    Ok(())
}

/// Writes the checkpoint (weights, moments, then `state`), copies the weights to `export`
/// and draws `curve_columns` of `out/log.csv` into `out/loss_curve.png`.
fn save<S: Serialize>(
    out: &Path,
    varmap: &VarMap,
    optimizer: &AdamW,
    state: &S,
    export: &Path,
    curve_columns: &[&str],
) -> Result<(), TrainError> {
    let dir = checkpoint_dir(out);
    let weights = dir.join("weights.safetensors");
    let tmp = dir.join("weights.safetensors.tmp");
    varmap.save(&tmp)?;
    std::fs::rename(&tmp, &weights).map_err(io_error(&weights))?;
    let opt = dir.join("optimizer.safetensors");
    let tmp = dir.join("optimizer.safetensors.tmp");
    optimizer.save(&tmp)?;
    std::fs::rename(&tmp, &opt).map_err(io_error(&opt))?;
    let path = dir.join("state.json");
    let text = serde_json::to_string_pretty(state).expect("state serialises");
    std::fs::write(&path, text).map_err(io_error(&path))?;
    std::fs::copy(&weights, export).map_err(io_error(export))?;
    let png = out.join("loss_curve.png");
    crate::curve::plot_csv(&out.join("log.csv"), curve_columns, &png, 800, 480)?;
    Ok(())
}
