//! A run directory's checkpoint, shared by every trainer of the crate (StereoSplat's and the
//! enhancer's): `checkpoint/weights.safetensors`, `checkpoint/optimizer.safetensors` (AdamW
//! moments) and `checkpoint/state.json` (the trainer's own bookkeeping), written in that
//! order through temporary files so a state file always describes complete files; then the
//! exported weights and the loss curve of `log.csv`.

use std::path::{Path, PathBuf};

use candle_core::Var;
use candle_nn::VarMap;
use serde::de::DeserializeOwned;
use serde::Serialize;

use super::{AdamW, TrainError};

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
pub(crate) fn variables(varmap: &VarMap) -> Vec<(String, Var)> {
    varmap
        .data()
        .lock()
        .expect("varmap lock")
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect()
}

/// The state file of `out`'s checkpoint, if there is one.
pub(crate) fn read_state<S: DeserializeOwned>(out: &Path) -> Result<Option<S>, TrainError> {
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
pub(crate) fn load(
    out: &Path,
    varmap: &VarMap,
    optimizer: &mut AdamW,
    step: u64,
) -> Result<(), TrainError> {
    let dir = checkpoint_dir(out);
    let mut varmap = varmap.clone();
    varmap.load(dir.join("weights.safetensors"))?;
    optimizer.load(&dir.join("optimizer.safetensors"), step)?;
    Ok(())
}

/// Writes the checkpoint (weights, moments, then `state`), copies the weights to `export`
/// and draws `curve_columns` of `out/log.csv` into `out/loss_curve.png`.
pub(crate) fn save<S: Serialize>(
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
