//! What `bench pareto` writes: one [`PointResult`] per operating point measured, the points
//! that could not run and why, as `pareto.json`, a markdown table with the fronts marked
//! (`pareto.md`) and a two-panel chart (`pareto.png`: latency on a log axis against
//! bin-average PSNR, and against bin-average AbsRel).

use model::curve::scatter::{Panel, ScatterPoint};
use model::eval::EvalReport;
use serde::Serialize;

use super::front::{front, Better};
use crate::pipeline::operating::OperatingPoint;

/// The measurements of one operating point over the held-out bins.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PointResult {
    /// The point as it was given.
    pub point: OperatingPoint,
    /// The reconstructor's own name (`sgm`, `stereosplat-tiny`).
    pub method: String,
    /// Bins measured and scored.
    pub bins: usize,
    /// Bins whose reconstruction failed (skipped by the protocol).
    pub skipped_bins: usize,
    /// Median per-bin latency, stereo pair to published bin map (input downsizing,
    /// reconstructor, self-check and its fallback), milliseconds.
    pub latency_median_ms: f64,
    /// 90th percentile of the same, milliseconds.
    pub latency_p90_ms: f64,
    /// Highest resident memory of the process during one bin's path, MiB (see the report's
    /// `peak_memory`).
    pub peak_rss_mib: f64,
    /// Mean Gaussians per bin map.
    pub gaussians_per_bin: f64,
    /// Bin-average PSNR, dB.
    pub psnr: f64,
    /// Bin-average SSIM.
    pub ssim: f64,
    /// Bin-average LPIPS (`None` when run with `--no-lpips`).
    pub lpips: Option<f64>,
    /// Bin-average AbsRel against LiDAR.
    pub abs_rel: Option<f64>,
    /// Bin-average SqRel against LiDAR.
    pub sq_rel: Option<f64>,
    /// Bin-average PSNR on the pixels the input pair never saw (generated drives only).
    pub unseen_psnr: Option<f64>,
    /// Bins whose map failed the worker's self-check.
    pub checks_failed: usize,
    /// Bins whose map was replaced by SGM's (the node's default on a failed check).
    pub replaced_by_sgm: usize,
    /// On the latency-PSNR front.
    pub front_psnr: bool,
    /// On the latency-AbsRel front.
    pub front_abs_rel: bool,
}

impl PointResult {
    /// The figures of `eval` (latencies from its per-bin reconstruction times, which time the
    /// whole worker path) with the path's memory and check counts; fronts are set later.
    pub fn new(
        point: OperatingPoint,
        eval: &EvalReport,
        peak_rss_bytes: u64,
        checks_failed: usize,
        replaced_by_sgm: usize,
    ) -> Self {
        let mut ms: Vec<f64> = eval.bins.iter().map(|b| b.reconstruct_ms).collect();
        ms.sort_by(f64::total_cmp);
        let quantile = |q: f64| match ms.len() {
            0 => f64::NAN,
            n => ms[((q * n as f64).ceil() as usize).clamp(1, n) - 1],
        };
        let avg = eval.summary.average;
        Self {
            point,
            method: eval.method.clone(),
            bins: eval.bins.len(),
            skipped_bins: eval.skipped.len(),
            latency_median_ms: quantile(0.5),
            latency_p90_ms: quantile(0.9),
            peak_rss_mib: peak_rss_bytes as f64 / (1 << 20) as f64,
            gaussians_per_bin: eval.mean_gaussians,
            psnr: avg.psnr,
            ssim: avg.ssim,
            lpips: avg.lpips,
            abs_rel: avg.abs_rel,
            sq_rel: avg.sq_rel,
            unseen_psnr: avg.unseen_psnr,
            checks_failed,
            replaced_by_sgm,
            front_psnr: false,
            front_abs_rel: false,
        }
    }
}

/// A point that did not run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SkippedPoint {
    /// The point's name.
    pub name: String,
    /// Why (a missing weight file, a setting the preset refuses).
    pub reason: String,
}

/// The whole run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParetoReport {
    /// The data root and sequence the bins came from.
    pub data: String,
    /// See `data`.
    pub sequence: String,
    /// Frames between bin starts.
    pub stride: usize,
    /// Image size the bins are scored at.
    pub size: (u32, u32),
    /// The rasterizer of the scoring renders.
    pub raster: String,
    /// Threads the reconstructors ran on.
    pub threads: usize,
    /// How `peak_rss_mib` was measured.
    pub peak_memory: String,
    /// Every measured point, fronts marked.
    pub points: Vec<PointResult>,
    /// Points that did not run.
    pub skipped: Vec<SkippedPoint>,
}

impl ParetoReport {
    /// Marks each point's place on the two fronts (median latency against PSNR, and
    /// against AbsRel; a point without AbsRel is on no AbsRel front).
    pub fn mark_fronts(&mut self) {
        let on = |q: &dyn Fn(&PointResult) -> f64, better| {
            let pts: Vec<(f64, f64)> = self
                .points
                .iter()
                .map(|p| (p.latency_median_ms, q(p)))
                .collect();
            front(&pts, better)
        };
        let psnr = on(&|p| p.psnr, Better::Higher);
        let abs_rel = on(&|p| p.abs_rel.unwrap_or(f64::NAN), Better::Lower);
        for ((p, a), b) in self.points.iter_mut().zip(psnr).zip(abs_rel) {
            p.front_psnr = a;
            p.front_abs_rel = b;
        }
    }

    /// The table: one row per point, `*` on the fronts.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "# Speed against accuracy\n\n{} bins of `{}` ({}, {}x{}, a bin every {} frames), \
             renders on {}, {} threads. Latency: stereo pair to published bin map (the \
             node's worker path). Memory: {}. `*`: on the front (no other point both \
             faster and better).\n\n",
            self.points.first().map_or(0, |p| p.bins),
            self.sequence,
            self.data,
            self.size.0,
            self.size.1,
            self.stride,
            self.raster,
            self.threads,
            self.peak_memory,
        );
        s.push_str(
            "| point | settings | ms p50 | ms p90 | peak MiB | Gaussians | PSNR | SSIM | LPIPS \
             | AbsRel | SqRel | unseen PSNR | SGM fallbacks | front PSNR | front AbsRel |\n\
             |---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---:|:---:|\n",
        );
        for p in &self.points {
            s.push_str(&format!(
                "| {} | {} | {:.1} | {:.1} | {:.0} | {:.0} | {:.2} | {:.3} | {} | {} | {} | {} \
                 | {} | {} | {} |\n",
                p.point.name,
                settings_text(&p.point),
                p.latency_median_ms,
                p.latency_p90_ms,
                p.peak_rss_mib,
                p.gaussians_per_bin,
                p.psnr,
                p.ssim,
                table_cell(p.lpips, 3),
                table_cell(p.abs_rel, 4),
                table_cell(p.sq_rel, 3),
                table_cell(p.unseen_psnr, 2),
                p.replaced_by_sgm,
                front_mark(p.front_psnr),
                front_mark(p.front_abs_rel),
            ));
        }
        for k in &self.skipped {
            s.push_str(&format!("\nSkipped `{}`: {}.\n", k.name, k.reason));
        }
        s
    }

    /// The chart's two panels.
    pub fn panels(&self) -> Vec<Panel> {
        let panel = |title: &str, y_title: &str, y: &dyn Fn(&PointResult) -> (f64, bool)| Panel {
            title: title.into(),
            x_title: "latency per bin, ms (log scale)".into(),
            y_title: y_title.into(),
            log_x: true,
            points: self
                .points
                .iter()
                .map(|p| {
                    let (y, on_front) = y(p);
                    ScatterPoint {
                        label: p.point.name.clone(),
                        x: p.latency_median_ms,
                        y,
                        on_front,
                    }
                })
                .collect(),
        };
        vec![
            panel(
                "PSNR against latency (ringed: Pareto front)",
                "bin-average PSNR, dB (higher is better)",
                &|p| (p.psnr, p.front_psnr),
            ),
            panel(
                "AbsRel against latency (ringed: Pareto front)",
                "bin-average AbsRel (lower is better)",
                &|p| (p.abs_rel.unwrap_or(f64::NAN), p.front_abs_rel),
            ),
        ]
    }
}

/// A markdown table cell of an optional score: `-` when it was not measured.
pub fn table_cell(v: Option<f64>, decimals: usize) -> String {
    v.map_or("-".into(), |v| format!("{v:.decimals$}"))
}

/// The table's mark of a point on a front.
pub fn front_mark(on_front: bool) -> &'static str {
    if on_front {
        "*"
    } else {
        ""
    }
}

/// A point's knobs in one cell: method, preset, settings, scale and pairs where not default.
fn settings_text(p: &OperatingPoint) -> String {
    let mut parts = vec![p.method.method.clone()];
    parts.extend(p.method.preset.clone());
    parts.extend(p.method.settings.iter().map(|s| format!("`{s}`")));
    if p.scale != 1.0 {
        parts.push(format!("scale {}", p.scale));
    }
    if p.pairs != 1 {
        parts.push(format!("{} pairs", p.pairs));
    }
    if let Some(w) = &p.method.weights {
        parts.push(format!("weights `{}`", w.display()));
    }
    parts.join(", ")
}
