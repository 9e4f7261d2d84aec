//! A bin's map as the worker makes it, shared by the worker, `bench pareto`, `eval-map` and
//! the operating points' runners so that all of them time and score the same path.

use std::panic::{catch_unwind, AssertUnwindSafe};

use model::reconstruct::{Reconstructor, StereoView};
use renderer::GaussianSet;

use super::self_check::{CheckOutcome, SelfCheck};

/// A bin's map from its stereo pairs (the worker gives it the first), as the worker makes
/// it: the reconstructor, then the self-check on the first pair and what its policy does
/// with a failing map; a panic in the reconstructor
/// is caught and returned as the error. `bench pareto` and `eval-map` time and score
/// exactly this path.
pub fn bin_map(
    reconstructor: &mut dyn Reconstructor,
    self_check: &mut SelfCheck,
    views: &[StereoView<'_>],
) -> (Result<GaussianSet, String>, CheckOutcome) {
    let checked = catch_unwind(AssertUnwindSafe(|| {
        match (reconstructor.reconstruct(views), views.first()) {
            (Ok(set), Some(first)) => self_check.apply(reconstructor.name(), first, set),
            (Ok(set), None) => (Ok(set), CheckOutcome::default()),
            (Err(e), _) => (Err(e.to_string()), CheckOutcome::default()),
        }
    }));
    match checked {
        Ok(done) => done,
        Err(panic) => (
            Err(format!(
                "reconstructor panicked: {}",
                panic
                    .downcast_ref::<String>()
                    .map(String::as_str)
                    .or_else(|| panic.downcast_ref::<&str>().copied())
                    .unwrap_or("(no message)")
            )),
            CheckOutcome::default(),
        ),
    }
}
