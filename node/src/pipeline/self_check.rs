//! What the worker does with the self-check (`model::consistency`) of every bin's map: the
//! check runs on the bin's own stereo pair, and a map that fails it is published flagged,
//! published with its opacity and confidence lowered, or replaced by the classical SGM
//! baseline's map (itself checked), as [`OnCheckFail`] says.
//!
//! The default is [`OnCheckFail::Sgm`]: the learned model is the reconstructor most likely
//! to fail (images unlike its training data), and SGM, which matches the pair it is given
//! rather than recalling a learned prior, is the one that holds up there; it costs an SGM
//! run only on the bins that failed. A flag alone leaves the garbage in the map of every
//! subscriber that ignores it, and lowered opacity still fuses it.

use model::baseline::{SgmConfig, SgmReconstructor};
use model::consistency::{check, CheckReport, CheckSettings, Verdict};
use model::reconstruct::{Reconstructor, StereoView};
use renderer::GaussianSet;

/// What the node does with a bin whose map fails the self-check.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OnCheckFail {
    /// Publish the map as it is; the bin's latency message and the counters say it failed.
    Flag,
    /// Publish the map with every opacity and confidence scaled by [`LOWERED_FACTOR`], so
    /// renders and the global map's fusion give it little weight.
    LowerOpacity,
    /// Reconstruct the bin with SGM instead and publish that (checked too: flagged when it
    /// fails as well). With SGM as the node's method this is [`OnCheckFail::Flag`].
    #[default]
    Sgm,
}

/// The factor [`OnCheckFail::LowerOpacity`] scales opacity and confidence by.
pub const LOWERED_FACTOR: f32 = 0.1;

/// What the node did about a bin's check.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CheckAction {
    /// Nothing: the check passed, was undetermined or did not run.
    #[default]
    None,
    /// Failed and published as it was.
    Flagged,
    /// Failed and published with opacity and confidence lowered.
    LoweredOpacity,
    /// Failed and replaced by SGM's map.
    Sgm,
}

impl CheckAction {
    /// The code in `BinLatency.check_action`: 0 none, 1 flagged, 2 opacity lowered, 3 SGM.
    pub fn code(self) -> u8 {
        match self {
            CheckAction::None => 0,
            CheckAction::Flagged => 1,
            CheckAction::LoweredOpacity => 2,
            CheckAction::Sgm => 3,
        }
    }
}

/// The code of a verdict in `BinLatency`: 0 not run, 1 pass, 2 fail, 3 undetermined.
pub fn verdict_code(report: Option<&CheckReport>) -> u8 {
    match report.map(|r| r.verdict) {
        None => 0,
        Some(Verdict::Pass) => 1,
        Some(Verdict::Fail) => 2,
        Some(Verdict::Undetermined) => 3,
    }
}

/// A bin's self-check and what came of it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CheckOutcome {
    /// The check of the node's method's map (`None`: no map to check).
    pub primary: Option<CheckReport>,
    /// What was done about it.
    pub action: CheckAction,
    /// The check of SGM's map when it replaced the primary one.
    pub fallback: Option<CheckReport>,
}

impl CheckOutcome {
    /// Whether the published map failed its check (the primary's, or SGM's after a
    /// fallback): the bin is published flagged.
    pub fn flagged(&self) -> bool {
        let published = self.fallback.as_ref().or(self.primary.as_ref());
        published.is_some_and(|r| r.verdict == Verdict::Fail)
    }
}

/// The worker's self-check: the policy and the SGM fallback, made when first needed.
pub struct SelfCheck {
    on_fail: OnCheckFail,
    settings: CheckSettings,
    sgm: Option<SgmReconstructor>,
}

impl SelfCheck {
    /// A check with the default thresholds acting on failures as `on_fail` says.
    pub fn new(on_fail: OnCheckFail) -> Self {
        Self {
            on_fail,
            settings: CheckSettings::default(),
            sgm: None,
        }
    }

    /// Checks `set`, made by `method` from `view`, and applies the policy: returns the set to
    /// publish (or SGM's error when the fallback failed to reconstruct) and the outcome.
    pub fn apply(
        &mut self,
        method: &str,
        view: &StereoView<'_>,
        mut set: GaussianSet,
    ) -> (Result<GaussianSet, String>, CheckOutcome) {
        let report = check(view, &set, &self.settings);
        let mut outcome = CheckOutcome {
            primary: Some(report),
            ..CheckOutcome::default()
        };
        if report.verdict != Verdict::Fail {
            return (Ok(set), outcome);
        }
        match self.on_fail {
            OnCheckFail::Sgm if method != "sgm" => {
                outcome.action = CheckAction::Sgm;
                let sgm = self
                    .sgm
                    .get_or_insert_with(|| SgmReconstructor::new(SgmConfig::default()));
                let result = sgm.reconstruct(&[*view]).map_err(|e| e.to_string());
                if let Ok(s) = &result {
                    outcome.fallback = Some(check(view, s, &self.settings));
                }
                (result, outcome)
            }
            OnCheckFail::LowerOpacity => {
                outcome.action = CheckAction::LoweredOpacity;
                for o in set.opacities.iter_mut().chain(set.confidences.iter_mut()) {
                    *o *= LOWERED_FACTOR;
                }
                (Ok(set), outcome)
            }
            OnCheckFail::Flag | OnCheckFail::Sgm => {
                outcome.action = CheckAction::Flagged;
                (Ok(set), outcome)
            }
        }
    }
}
