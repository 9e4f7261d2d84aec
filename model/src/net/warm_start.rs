//! Warm starts: a network's variables filled from a weight file that holds only part of
//! them (the shipped cost-volume weights for a network that also has the volume branch).
//! Every tensor of the file whose name the network has is loaded (its shape must match);
//! the network's other variables keep their fresh values and are reported by name.

use std::path::Path;

use candle_core::{Device, Tensor};
use candle_nn::VarMap;

/// What [`load_matching`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WarmStart {
    /// Variables loaded from the file.
    pub loaded: usize,
    /// Variables the file does not hold (they keep their fresh values), sorted.
    pub fresh: Vec<String>,
    /// Tensors of the file the network does not have (ignored), sorted.
    pub unused: Vec<String>,
}

impl WarmStart {
    /// The distinct top-level prefixes of the fresh variables (`volume` for `volume.*`),
    /// for a one-line report.
    pub fn fresh_prefixes(&self) -> Vec<String> {
        let mut p: Vec<String> = self
            .fresh
            .iter()
            .map(|n| n.split('.').next().unwrap_or(n).to_string())
            .collect();
        p.dedup();
        p
    }
}

/// Loads every tensor of the safetensors file at `path` that `varmap` has a variable of the
/// same name for. A tensor whose shape differs from its variable's is an error (the file is
/// of another preset), so nothing is half-loaded silently.
pub fn load_matching(varmap: &VarMap, path: &Path) -> candle_core::Result<WarmStart> {
    let file = crate::assets::load_tensors(path, &Device::Cpu)?;
    let data = varmap
        .data()
        .lock()
        .map_err(|_| candle_core::Error::Msg("variable map poisoned".into()))?;
    let mut report = WarmStart::default();
    for (name, var) in data.iter() {
        match file.get(name) {
            Some(t) if t.dims() == var.dims() => {
                var.set(&t.to_dtype(var.dtype())?.to_device(var.device())?)?;
                report.loaded += 1;
            }
            Some(t) => candle_core::bail!(
                "{}: {name} is {:?} in the file but {:?} in the network",
                path.display(),
                t.dims(),
                var.dims()
            ),
            None => report.fresh.push(name.clone()),
        }
    }
    report.unused = file
        .keys()
        .filter(|k| !data.contains_key(*k))
        .cloned()
        .collect();
    report.fresh.sort();
    report.unused.sort();
    Ok(report)
}

/// The variables of `varmap` as plain tensors (no gradient tracked, so candle's inference
/// kernels run), by name.
pub fn frozen(varmap: &VarMap) -> candle_core::Result<std::collections::HashMap<String, Tensor>> {
    Ok(varmap
        .data()
        .lock()
        .map_err(|_| candle_core::Error::Msg("variable map poisoned".into()))?
        .iter()
        .map(|(k, v)| (k.clone(), v.as_tensor().detach()))
        .collect())
}
