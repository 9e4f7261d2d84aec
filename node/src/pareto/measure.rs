//! Operating points measured side by side: each through the node worker's own path on the
//! same bins, scored by the evaluation protocol (what `bench pareto` reports and what the
//! latency budget's `auto` table is made from).

use anyhow::Result;
use model::eval::{evaluate, EvalConfig, EvalReport, Raster};
use model::kitti360::Sequence;
use model::reconstruct::Reconstructor;

use super::{PointResult, SkippedPoint, WorkerPath};
use crate::pipeline::operating::{Availability, OperatingPoint};
use crate::pipeline::self_check::OnCheckFail;
use crate::progress;

/// What [`measure_points`] found.
pub struct Measured {
    /// The points that ran, in the list's order.
    pub points: Vec<PointResult>,
    /// The points that could not run, and why.
    pub skipped: Vec<SkippedPoint>,
    /// Whether the peak memory could be reset before every bin.
    pub peak_reset: bool,
}

/// Every point of `points` through the node worker's path on `sequence`'s bins, scored by
/// the evaluation protocol (`config`; its input pairs set per point); a point whose
/// weights are missing or do not load is skipped with the reason.
pub fn measure_points(
    points: &[OperatingPoint],
    sequence: &Sequence,
    raster: &mut Raster,
    config: &mut EvalConfig,
    bin_length: f64,
) -> Result<Measured> {
    let mut measured = Measured {
        points: Vec::new(),
        skipped: Vec::new(),
        peak_reset: true,
    };
    for (k, point) in points.iter().enumerate() {
        if let Availability::Missing(path) = point.availability() {
            let reason = format!("weight file {} does not exist", path.display());
            eprintln!("skipping `{}`: {reason}", point.name);
            measured.skipped.push(SkippedPoint {
                name: point.name.clone(),
                reason,
            });
            continue;
        }
        let inner = match point.method.build() {
            Ok(r) => r,
            Err(e) => {
                // The first line: a backend error may carry a backtrace after it.
                let reason = format!("{e:#}").lines().next().unwrap_or("").to_string();
                eprintln!("skipping `{}`: {reason}", point.name);
                measured.skipped.push(SkippedPoint {
                    name: point.name.clone(),
                    reason,
                });
                continue;
            }
        };
        let mut path = WorkerPath::new(inner, point.scale, OnCheckFail::default());
        config.input_pairs = point.pairs;
        let label = format!("{}/{} {}", k + 1, points.len(), point.name);
        let bar = progress::bar(0, &label);
        let (bins, skipped) = evaluate(
            sequence,
            &mut path,
            raster,
            config,
            &mut progress::hook(&bar),
        )?;
        bar.finish_and_clear();
        let eval = EvalReport::new(
            path.name().to_string(),
            raster.name(),
            bin_length,
            (config.depth.min_depth, config.depth.max_depth),
            bins,
            skipped,
        );
        measured.peak_reset &= path.peak_reset;
        let result = PointResult::new(
            point.clone(),
            &eval,
            path.peak_rss_bytes,
            path.checks_failed,
            path.replaced_by_sgm,
        );
        eprintln!(
            "{:>16}: {:.1} ms p50, {:.2} dB, AbsRel {:.4}, {:.0} Gaussians",
            point.name,
            result.latency_median_ms,
            result.psnr,
            result.abs_rel.unwrap_or(f64::NAN),
            result.gaussians_per_bin
        );
        measured.points.push(result);
    }
    Ok(measured)
}
