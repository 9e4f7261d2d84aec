//! The node worker's path from a stereo pair to a published bin map, as a [`Reconstructor`]
//! that the evaluation protocol can time and score: the pair (and its cameras) downsized by
//! the operating point's input scale as the node downsizes to its working size, the
//! reconstructor, then the worker's self-check and its policy
//! ([`crate::pipeline::bin_map::bin_map`]). Each call also records the process's peak
//! resident memory during it (the peak is reset before the call, [`reset_peak_rss`]).

use model::reconstruct::{ReconstructError, Reconstructor, StereoView};
use renderer::GaussianSet;

use crate::memory::{peak_rss_bytes, reset_peak_rss};
use crate::pipeline::bin_map::bin_map;
use crate::pipeline::operating::with_scaled_views;
use crate::pipeline::self_check::{CheckAction, OnCheckFail, SelfCheck};

/// A reconstructor run as the node's worker runs it, with per-call memory and check counts.
pub struct WorkerPath {
    inner: Box<dyn Reconstructor + Send>,
    self_check: SelfCheck,
    scale: f64,
    /// Largest peak resident memory seen during a call, bytes.
    pub peak_rss_bytes: u64,
    /// Whether the peak could be reset before each call (else it is the process's peak).
    pub peak_reset: bool,
    /// Calls whose map failed the self-check.
    pub checks_failed: usize,
    /// Calls whose map was replaced by SGM's (the node's default policy on a failed check).
    pub replaced_by_sgm: usize,
}

impl WorkerPath {
    /// `inner` behind the worker's self-check (policy `on_fail`), inputs scaled by `scale`
    /// in (0, 1].
    pub fn new(inner: Box<dyn Reconstructor + Send>, scale: f64, on_fail: OnCheckFail) -> Self {
        Self {
            inner,
            self_check: SelfCheck::new(on_fail),
            scale,
            peak_rss_bytes: 0,
            peak_reset: true,
            checks_failed: 0,
            replaced_by_sgm: 0,
        }
    }
}

impl Reconstructor for WorkerPath {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn reconstruct(&mut self, views: &[StereoView<'_>]) -> Result<GaussianSet, ReconstructError> {
        self.peak_reset &= reset_peak_rss();
        let (inner, self_check) = (self.inner.as_mut(), &mut self.self_check);
        let (result, check) =
            with_scaled_views(views, self.scale, |views| bin_map(inner, self_check, views));
        self.peak_rss_bytes = self.peak_rss_bytes.max(peak_rss_bytes());
        self.checks_failed += usize::from(check.action != CheckAction::None);
        self.replaced_by_sgm += usize::from(check.action == CheckAction::Sgm);
        result.map_err(ReconstructError::Backend)
    }
}
