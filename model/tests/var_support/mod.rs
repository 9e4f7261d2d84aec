//! What tests comparing the inference path with the training path share.

use std::collections::HashMap;

use candle_core::Tensor;
use candle_nn::VarMap;

/// The variables of `varmap` as plain tensors: loaded through `VarBuilder::from_tensors`,
/// they give the same network with no gradient tracked, so the inference kernels run.
pub fn frozen(varmap: &VarMap) -> HashMap<String, Tensor> {
    varmap
        .data()
        .lock()
        .unwrap()
        .iter()
        .map(|(k, v)| (k.clone(), v.as_tensor().detach()))
        .collect()
}
