//! What the stability tests share: every value of a tensor finite, every gradient a
//! backward pass gave to a variable map finite.

use candle_core::{backprop::GradStore, DType, Tensor};
use candle_nn::VarMap;

/// Fails unless every value of `t` is finite.
pub fn assert_finite(t: &Tensor, what: &str) {
    let v: Vec<f64> = t
        .flatten_all()
        .unwrap()
        .to_dtype(DType::F64)
        .unwrap()
        .to_vec1()
        .unwrap();
    let bad = v.iter().filter(|x| !x.is_finite()).count();
    assert_eq!(bad, 0, "{what}: {bad} of {} values not finite", v.len());
}

/// Fails unless every gradient in `grads` of a variable of `varmap` is finite; returns how
/// many variables got one.
pub fn assert_finite_gradients(varmap: &VarMap, grads: &GradStore, what: &str) -> usize {
    let mut with_grad = 0;
    for var in varmap.all_vars() {
        if let Some(g) = grads.get(var.as_tensor()) {
            assert_finite(g, &format!("{what}: gradient"));
            with_grad += 1;
        }
    }
    with_grad
}
