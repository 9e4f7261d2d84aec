//! The CSV training log: one row per step, kept consistent with the checkpoint on resume
//! (rows after the checkpoint's step are dropped, since those steps run again). The columns
//! are the caller's: StereoSplat's training writes [`LOG_COLUMNS`], the enhancer's its own.

use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

use super::StepReport;

/// The log's columns, in order.
pub const LOG_COLUMNS: &[&str] = &[
    "step",
    "loss",
    "l2",
    "lpips",
    "rendered_depth",
    "estimated_depth",
    "confidence",
    "lr",
    "grad_norm",
    "pairs",
    "steps_per_s",
    "elapsed_s",
    "occupancy",
    "volume_l2",
    "volume_gaussians",
];

/// An open log.
pub struct TrainLog {
    file: File,
}

impl TrainLog {
    /// Opens `path` with `columns` (the first must be the step), keeping the rows up to
    /// `keep_until` (inclusive).
    pub fn open(path: &Path, columns: &[&str], keep_until: u64) -> std::io::Result<Self> {
        let mut kept = vec![columns.join(",")];
        if keep_until > 0 && path.exists() {
            for line in BufReader::new(File::open(path)?).lines().skip(1) {
                let line = line?;
                let step = line.split(',').next().and_then(|s| s.parse::<u64>().ok());
                if step.is_some_and(|s| s <= keep_until) {
                    kept.push(line);
                }
            }
        }
        std::fs::write(path, kept.join("\n") + "\n")?;
        Ok(Self {
            file: OpenOptions::new().append(true).open(path)?,
        })
    }

    /// Appends one row, already formatted (comma-separated, the step first).
    pub fn append_row(&mut self, row: &str) -> std::io::Result<()> {
        writeln!(self.file, "{row}")
    }

    /// Appends a StereoSplat training step's row ([`LOG_COLUMNS`]).
    pub fn append(&mut self, r: &StepReport) -> std::io::Result<()> {
        writeln!(
            self.file,
            "{},{:.6},{:.6},{:.6},{:.4},{:.4},{:.6},{:.3e},{:.4},{},{:.4},{:.1},{:.6},{:.6},{}",
            r.step,
            r.loss,
            r.l2,
            r.lpips,
            r.rendered_depth,
            r.estimated_depth,
            r.confidence,
            r.lr,
            r.grad_norm,
            r.pairs,
            r.steps_per_s,
            r.elapsed_s,
            r.occupancy,
            r.volume_l2,
            r.volume_gaussians
        )
    }
}
