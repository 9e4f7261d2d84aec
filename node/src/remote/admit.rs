//! What the node takes from a worker process's answer, and what it takes from its own copy
//! of the bin instead: a remote bin is the node's bin, and a worker's reply cannot put into
//! the map anything the node's own worker thread would not have.
//!
//! The node keeps the [`Job`] it sent (the query's, [`super::pool`]) and holds every map
//! reply to it:
//!
//! - **Bin and pose.** The map must be of the job's bin, at the job's pose: the pose the
//!   node's own thread gives a bin's map (`run_job`: the bin frame is the job's first left
//!   camera, `frame.left_to_world`). The wire carries the pose's exact bits, so an honest
//!   worker's reply always holds exactly that pose. A reply that does not is **dropped**,
//!   not given the node's pose: it was not made from the frame the node sent (or was
//!   changed on the way), so its Gaussians, in a frame the node never sent, are wrong at
//!   any pose. A map that passes is fused at the node's own copy of the pose all the same.
//! - **Stamps.** The source, arrival and bin-open stamps are the node's, always taken from
//!   the job; the worker's model and render stamps (its clock) are kept.
//! - **Values.** Opacity and confidence are in [0, 1] by construction (sigmoids, SGM's
//!   `floor + (1 - floor) x confidence`). A reply with one outside (1e30 would win its cells
//!   in the global map for ever: takeover needs a strictly higher confidence) or infinite is
//!   dropped; a NaN is left to the fusion, which skips a Gaussian with a NaN field as it
//!   does in the node's own maps. The global map clamps both to [0, 1] on every path in as
//!   well (`crate::fusion`).
//! - **Self-check.** The node runs the self-check itself on the map it received, with the
//!   worker thread's settings, and its report replaces the worker's. The check is
//!   deterministic (one sequential pass over at most 4096 grid cells and 2^20 centres), so
//!   an honest worker's report equals the node's bit for bit; a reply whose report, or
//!   whose action, is not what the node's check and the node's `--on-check-fail` policy
//!   give is dropped. Re-running rather than re-checking cheaply: the cost is bounded by
//!   the check's own grid (3.4 ms a bin at 544x112, median of `stereosplat bench check`'s
//!   96 checks on 2 cores, 8.7 ms at most; docs/workers.md), small against the bin's model
//!   time, and only the full check catches a map of garbage reported as passing. Two
//!   claims cannot be re-run: that the learned map failed before SGM's replaced it (the
//!   learned map is not sent), and the report of a map whose opacities were lowered
//!   (checked as lowered: every opacity and confidence at most [`LOWERED_FACTOR`], and the
//!   node's check of it, with the opacity floor lowered alike, must fail too).
//! - **Size.** A reply larger than the bin can need ([`Rules::reply_limit`]) is dropped
//!   without being decoded.
//!
//! A worker whose reply is dropped gets no more bins (until its liveliness token goes and
//! comes back), and its bin goes to another worker: left in the pool, it would take the
//! bin's next attempts too. Each drop is counted ([`Rejection::counter`]).

use model::baseline::SgmConfig;
use model::consistency::{check, CheckReport, CheckSettings, Verdict};
use model::frame::Side;
use model::reconstruct::StereoView;
use renderer::gaussians::LengthMismatch;
use renderer::GaussianSet;

use super::fingerprint::Fingerprint;
use crate::pipeline::self_check::{CheckAction, CheckOutcome, OnCheckFail, LOWERED_FACTOR};
use crate::pipeline::worker::{Job, Output, Rendered};

/// Bytes of a reply beside its Gaussians or its render: the CDR header, stamps, the check,
/// an error message.
pub const REPLY_OVERHEAD: usize = 64 * 1024;

/// Bytes a Gaussian takes in a map reply: 15 floats (mean, log scale, rotation, colour,
/// opacity, confidence).
pub const BYTES_PER_GAUSSIAN: usize = 60;

/// The largest greeting reply the node reads (a fingerprint and a thread count).
pub const HELLO_LIMIT: usize = REPLY_OVERHEAD;

/// The most Gaussians any reconstructor caps its maps at (the `paper` preset's), taken for
/// a fingerprint whose own cap cannot be read.
const LARGEST_CAP: usize = 2_000_000;

/// Why a worker's reply was dropped.
#[derive(Debug, thiserror::Error)]
pub enum Rejection {
    /// The reply is larger than the bin can need.
    #[error("its reply of {bytes} bytes is over the bin's limit of {limit}")]
    TooLarge {
        /// The reply's size.
        bytes: usize,
        /// The bin's limit.
        limit: usize,
    },
    /// More replies came for one bin than a worker sends (a map and its render).
    #[error("it sent more than {0} replies for one bin")]
    TooMany(usize),
    /// The map is of another bin.
    #[error("its map is of bin {got}, not {want}")]
    Bin {
        /// The bin the reply names.
        got: u64,
        /// The bin the node sent.
        want: u64,
    },
    /// The map's pose is not the bin's.
    #[error("its map's pose is not the bin's")]
    Pose,
    /// An opacity or confidence outside [0, 1].
    #[error("its map's {what} {index} is {value}, outside [0, 1]")]
    Values {
        /// `opacity` or `confidence`.
        what: &'static str,
        /// The Gaussian.
        index: usize,
        /// The value.
        value: f32,
    },
    /// The map's arrays differ in length.
    #[error("its map's arrays differ in length")]
    Lengths(#[source] LengthMismatch),
    /// The node's self-check, or the node's policy, disagrees with the reply's.
    #[error("its self-check disagrees with the node's: {0}")]
    Check(String),
    /// The render is of another bin or another size.
    #[error("its render {0}")]
    Render(String),
}

impl Rejection {
    /// The counter a drop for this reason goes to.
    pub fn counter(&self) -> &'static str {
        match self {
            Rejection::TooLarge { .. } => "discarded/worker_reply_size",
            Rejection::TooMany(_) => "discarded/worker_reply_count",
            Rejection::Bin { .. } | Rejection::Pose => "discarded/worker_pose",
            Rejection::Values { .. } | Rejection::Lengths(_) => "discarded/worker_values",
            Rejection::Check(_) => "discarded/worker_check",
            Rejection::Render(_) => "discarded/worker_render",
        }
    }
}

/// What the node holds its workers' replies to.
#[derive(Clone, Copy, Debug)]
pub struct Rules {
    /// The node's policy for a map failing its self-check.
    pub on_check_fail: OnCheckFail,
    /// The node's method is SGM (its `Sgm` policy then only flags, as on the node).
    pub sgm_method: bool,
    /// The most Gaussians a map of the node's reconstructor holds.
    pub max_gaussians: usize,
}

impl Rules {
    /// The rules of a node whose workers must run `fingerprint` and treat a failing map as
    /// `on_check_fail` says.
    pub fn of(fingerprint: &Fingerprint, on_check_fail: OnCheckFail) -> Self {
        Self {
            on_check_fail,
            sgm_method: fingerprint.method == "sgm",
            max_gaussians: max_gaussians(fingerprint),
        }
    }

    /// The largest reply a worker may send for `job`: a map of the reconstructor's most
    /// Gaussians, or a render of the job's image (or of its camera's size, when larger) as
    /// floats, plus [`REPLY_OVERHEAD`].
    pub fn reply_limit(&self, job: &Job) -> usize {
        let (image, k) = (&job.frame.left, &job.rig.intrinsics);
        let (w, h) = (image.width.max(k.width), image.height.max(k.height));
        reply_limit(self.max_gaussians, w, h)
    }

    /// The action the node's worker thread takes on a map whose check says `verdict`.
    fn action(&self, verdict: Verdict) -> CheckAction {
        match (verdict, self.on_check_fail) {
            (Verdict::Pass | Verdict::Undetermined, _) => CheckAction::None,
            (Verdict::Fail, OnCheckFail::Flag) => CheckAction::Flagged,
            (Verdict::Fail, OnCheckFail::LowerOpacity) => CheckAction::LoweredOpacity,
            (Verdict::Fail, OnCheckFail::Sgm) if self.sgm_method => CheckAction::Flagged,
            (Verdict::Fail, OnCheckFail::Sgm) => CheckAction::Sgm,
        }
    }
}

/// The largest reply for a bin of `width` x `height` pixels whose maps hold at most
/// `max_gaussians`: the larger of the map and a render as floats, plus
/// [`REPLY_OVERHEAD`].
pub fn reply_limit(max_gaussians: usize, width: u32, height: u32) -> usize {
    let map = max_gaussians.saturating_mul(BYTES_PER_GAUSSIAN);
    let render = (width as usize)
        .saturating_mul(height as usize)
        .saturating_mul(12);
    REPLY_OVERHEAD.saturating_add(map.max(render))
}

/// The most Gaussians in a map of the reconstructor `fingerprint` names: its own cap
/// (`max_gaussians` of its preset and settings, which every reconstructor and the
/// progressive pass cut their maps to), or SGM's when a failing map may be replaced by
/// SGM's, whichever is larger.
pub fn max_gaussians(fingerprint: &Fingerprint) -> usize {
    let settings = &fingerprint.settings;
    let own = match fingerprint.method.as_str() {
        "sgm" => model::net::apply_settings(SgmConfig::default(), settings)
            .ok()
            .map(|c| c.max_gaussians),
        "stereosplat" => model::net::Config::preset(&fingerprint.preset)
            .ok()
            .and_then(|c| c.with_settings(settings).ok())
            .map(|c| c.max_gaussians),
        _ => None,
    };
    own.unwrap_or(LARGEST_CAP)
        .max(SgmConfig::default().max_gaussians)
}

/// The view the node's worker thread checks `job`'s map against (`run_job`'s).
fn view(job: &Job) -> StereoView<'_> {
    let origin = job.frame.left_to_world;
    StereoView {
        left: &job.frame.left,
        right: &job.frame.right,
        left_camera: job.rig.local_camera(origin, origin, Side::Left),
        right_camera: job.rig.local_camera(origin, origin, Side::Right),
    }
}

/// `out`, a worker's map of `job`, as the node takes it (the module doc): of the job's bin
/// and pose, with the job's stamps, values in range and the node's own self-check, or why
/// it is dropped.
pub fn admit_map(job: &Job, rules: &Rules, mut out: Output) -> Result<Output, Rejection> {
    if out.bin_id != job.bin_id {
        return Err(Rejection::Bin {
            got: out.bin_id,
            want: job.bin_id,
        });
    }
    if out.bin_to_world != job.frame.left_to_world {
        return Err(Rejection::Pose);
    }
    out.bin_to_world = job.frame.left_to_world;
    out.stamps.source_ns = job.stamps.source_ns;
    out.stamps.arrival_ns = job.stamps.arrival_ns;
    out.stamps.opened_ns = job.stamps.opened_ns;
    out.queue_depth = 0;
    out.point = 0;
    if let Ok(set) = &out.result {
        in_range(set)?;
        out.check = recheck(job, rules, set, out.check)?;
    }
    Ok(out)
}

/// A worker's render of `job`, or why it is dropped: of the job's bin, at the job's size.
pub fn admit_render(job: &Job, r: Rendered) -> Result<Rendered, Rejection> {
    if r.bin_id != job.bin_id {
        return Err(Rejection::Render(format!(
            "is of bin {}, not {}",
            r.bin_id, job.bin_id
        )));
    }
    let k = &job.rig.intrinsics;
    if let Ok(image) = &r.image {
        let values = 3 * image.width as u64 * image.height as u64;
        if (image.width, image.height) != (k.width, k.height) || image.data.len() as u64 != values {
            return Err(Rejection::Render(format!(
                "is {}x{} ({} values), not the bin's {}x{}",
                image.width,
                image.height,
                image.data.len(),
                k.width,
                k.height
            )));
        }
    }
    Ok(r)
}

/// Equal arrays, and every opacity and confidence in [0, 1] or NaN (the fusion skips a
/// Gaussian with a NaN field).
fn in_range(set: &GaussianSet) -> Result<(), Rejection> {
    set.check_lengths().map_err(Rejection::Lengths)?;
    for (what, values) in [
        ("opacity", &set.opacities),
        ("confidence", &set.confidences),
    ] {
        if let Some((index, &value)) = values
            .iter()
            .enumerate()
            .find(|(_, v)| !v.is_nan() && !(0.0..=1.0).contains(*v))
        {
            return Err(Rejection::Values { what, index, value });
        }
    }
    Ok(())
}

/// The node's own check of `set`, `job`'s map, in place of the worker's `claimed` one
/// (the module doc says what is compared).
fn recheck(
    job: &Job,
    rules: &Rules,
    set: &GaussianSet,
    claimed: CheckOutcome,
) -> Result<CheckOutcome, Rejection> {
    let disagree = |why: String| Err(Rejection::Check(why));
    let settings = CheckSettings::default();
    let failed = |r: &Option<CheckReport>| r.is_some_and(|r| r.verdict == Verdict::Fail);
    match claimed.action {
        CheckAction::None | CheckAction::Flagged => {
            let own = check(&view(job), set, &settings);
            let action = rules.action(own.verdict);
            if claimed.primary != Some(own)
                || claimed.action != action
                || claimed.fallback.is_some()
            {
                return disagree(format!(
                    "the node's check is {} ({:?}); the worker's {:?}, {:?}",
                    own.verdict.name(),
                    action,
                    claimed.primary.map(|r| r.verdict),
                    claimed.action
                ));
            }
            Ok(claimed)
        }
        CheckAction::Sgm => {
            if rules.action(Verdict::Fail) != CheckAction::Sgm || !failed(&claimed.primary) {
                return disagree("an SGM fallback the node's policy does not take".into());
            }
            let own = check(&view(job), set, &settings);
            if claimed.fallback != Some(own) {
                return disagree(format!(
                    "the node's check of SGM's map is {}",
                    own.verdict.name()
                ));
            }
            Ok(claimed)
        }
        CheckAction::LoweredOpacity => {
            if rules.action(Verdict::Fail) != CheckAction::LoweredOpacity
                || !failed(&claimed.primary)
            {
                return disagree("lowered opacities the node's policy does not take".into());
            }
            let lowered = |v: &f32| v.is_nan() || *v <= LOWERED_FACTOR;
            if !set.opacities.iter().chain(&set.confidences).all(lowered) {
                return disagree("opacities said lowered are not".into());
            }
            let dimmed = CheckSettings {
                min_opacity: settings.min_opacity * LOWERED_FACTOR,
                ..settings
            };
            let own = check(&view(job), set, &dimmed);
            if own.verdict != Verdict::Fail {
                return disagree(format!(
                    "the node's check of the map before it was lowered is {}",
                    own.verdict.name()
                ));
            }
            Ok(CheckOutcome {
                primary: Some(own),
                ..claimed
            })
        }
    }
}

#[cfg(test)]
#[path = "admit_tests.rs"]
mod tests;
