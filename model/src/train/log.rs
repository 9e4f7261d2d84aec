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
    "matching",
];

/// An open log.
pub struct TrainLog {
    file: File,
}

impl TrainLog {
    /// Opens `path` with `columns` (the first must be the step), keeping the rows up to
    /// `keep_until` (inclusive). When the old header is a prefix of `columns` (a log from
    /// before columns were added, or resumed once since), rows short of `columns` are padded
    /// with 0, the value the added columns take when their part is off.
    pub fn open(path: &Path, columns: &[&str], keep_until: u64) -> std::io::Result<Self> {
        let mut kept = vec![columns.join(",")];
        if keep_until > 0 && path.exists() {
            let mut lines = BufReader::new(File::open(path)?).lines();
            let old = lines.next().transpose()?.unwrap_or_default();
            let old: Vec<&str> = old.split(',').collect();
            let padded = columns.starts_with(&old);
            for line in lines {
                let line = line?;
                let step = line.split(',').next().and_then(|s| s.parse::<u64>().ok());
                if step.is_some_and(|s| s <= keep_until) {
                    let missing = columns.len().saturating_sub(line.split(',').count());
                    kept.push(match padded {
                        true => line + &",0".repeat(missing),
                        false => line,
                    });
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
            "{},{:.6},{:.6},{:.6},{:.4},{:.4},{:.6},{:.3e},{:.4},{},{:.4},{:.1},{:.6},{:.6},{},{:.4}",
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
            r.volume_gaussians,
            r.matching
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_log_from_before_new_columns_is_padded_and_cut_at_the_checkpoint() {
        let dir = std::env::temp_dir().join(format!("stereosplat-log-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("log.csv");
        std::fs::write(&path, "step,loss\n1,0.5\n2,0.4\n3,0.3\n").unwrap();
        let mut log = TrainLog::open(&path, &["step", "loss", "extra", "more"], 2).unwrap();
        log.append_row("3,0.2,1,2").unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text,
            "step,loss,extra,more\n1,0.5,0,0\n2,0.4,0,0\n3,0.2,1,2\n"
        );
        // Resumed once already: the header is new, the old rows short.
        std::fs::write(&path, "step,loss,extra,more\n1,0.5\n2,0.4,1,2\n").unwrap();
        TrainLog::open(&path, &["step", "loss", "extra", "more"], 9).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, "step,loss,extra,more\n1,0.5,0,0\n2,0.4,1,2\n");
        // Another header: rows kept as they were.
        std::fs::write(&path, "step,other\n1,7\n").unwrap();
        TrainLog::open(&path, &["step", "loss"], 5).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "step,loss\n1,7\n");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
