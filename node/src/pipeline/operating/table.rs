//! The table of operating points the node chooses from when it has a latency budget: each
//! row an operating point ([`OperatingPoint`]: preset, input scale, Gaussian stride and the
//! other settings, as `bench pareto` runs them) with the worker time one bin took with it
//! and the quality it reached, both measured on this machine.
//!
//! The file is JSON, written by `stereosplat run --calibrate` (`operating_points.json`):
//!
//! ```json
//! {
//!   "size": [1408, 376],
//!   "source": "run --calibrate: ...",
//!   "rows": [
//!     { "point": { "name": "tiny", "preset": "tiny" }, "ms": 1580.0, "psnr": 23.6 }
//!   ]
//! }
//! ```
//!
//! `size` is the frame size the times were measured at, `ms` the median time of a bin's
//! model path on the worker (input scaling, model, self-check and its fallback; the render
//! is not in it), `psnr` the bin-average PSNR on generated validation drives. A `bench pareto` report (`pareto.json`) is read as a table too: its median
//! latencies and PSNRs become `ms` and `psnr`, at the report's size, and its points that run
//! more than one pair per bin (which the node's worker does not) are left out. Rows are kept most
//! accurate first (highest PSNR; the faster of two equal ones first).

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::pipeline::operating::OperatingPoint;

/// One operating point with its measured cost and quality.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableRow {
    /// The point (the node runs its first pair only: `pairs` must be 1).
    pub point: OperatingPoint,
    /// Median time of one bin's model path at the table's size, milliseconds.
    pub ms: f64,
    /// Bin-average PSNR on generated validation drives, dB.
    pub psnr: f64,
}

/// The operating points a node may run, most accurate first.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatingTable {
    /// Frame size (width, height) the times were measured at.
    pub size: (u32, u32),
    /// How the table was made (the command, the data its quality came from).
    #[serde(default)]
    pub source: String,
    /// The rows, most accurate first.
    pub rows: Vec<TableRow>,
}

/// Why a table could not be used.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The file could not be read.
    #[error("reading the operating points {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// Neither a table nor a `bench pareto` report.
    #[error("operating points {path}: neither a table (`rows`) nor a bench pareto report (`points`): {source}")]
    Syntax {
        /// The file.
        path: PathBuf,
        /// What the table reader said.
        #[source]
        source: serde_json::Error,
    },
    /// No rows.
    #[error("the operating points table has no rows")]
    Empty,
    /// Two rows share a name.
    #[error("operating point `{0}` is in the table twice")]
    DuplicateName(String),
    /// A row's figures or point cannot be used.
    #[error("operating point `{name}`: {what}")]
    Invalid {
        /// The row's point.
        name: String,
        /// What is wrong.
        what: String,
    },
}

/// The part of a `bench pareto` report a table takes.
#[derive(Deserialize)]
struct ParetoRows {
    size: (u32, u32),
    data: String,
    points: Vec<ParetoRow>,
}

#[derive(Deserialize)]
struct ParetoRow {
    point: OperatingPoint,
    latency_median_ms: f64,
    psnr: f64,
}

impl OperatingTable {
    /// A table of `rows` measured at `size`, checked and sorted most accurate first.
    pub fn new(size: (u32, u32), source: String, rows: Vec<TableRow>) -> Result<Self, TableError> {
        let mut table = Self { size, source, rows };
        table.check()?;
        table
            .rows
            .sort_by(|a, b| b.psnr.total_cmp(&a.psnr).then(a.ms.total_cmp(&b.ms)));
        Ok(table)
    }

    /// The table in `text`: a table's JSON or a `bench pareto` report's (`path` names it in
    /// errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, TableError> {
        match serde_json::from_str::<OperatingTable>(text) {
            Ok(t) => Self::new(t.size, t.source, t.rows),
            Err(table_err) => match serde_json::from_str::<ParetoRows>(text) {
                Ok(p) => Self::new(
                    p.size,
                    format!("bench pareto on {}", p.data),
                    p.points
                        .into_iter()
                        .filter(|r| r.point.pairs == 1)
                        .map(|r| TableRow {
                            point: r.point,
                            ms: r.latency_median_ms,
                            psnr: r.psnr,
                        })
                        .collect(),
                ),
                Err(_) => Err(TableError::Syntax {
                    path: path.to_path_buf(),
                    source: table_err,
                }),
            },
        }
    }

    /// The table in the file at `path`.
    pub fn load(path: &Path) -> Result<Self, TableError> {
        let text = std::fs::read_to_string(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// The table as the JSON [`Self::load`] reads.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a table serializes") + "\n"
    }

    /// The row that runs fastest by the table.
    pub fn fastest(&self) -> usize {
        (0..self.rows.len())
            .min_by(|&a, &b| self.rows[a].ms.total_cmp(&self.rows[b].ms))
            .unwrap_or(0)
    }

    fn check(&self) -> Result<(), TableError> {
        if self.rows.is_empty() {
            return Err(TableError::Empty);
        }
        let mut names = HashSet::new();
        for r in &self.rows {
            let invalid = |what: String| TableError::Invalid {
                name: r.point.name.clone(),
                what,
            };
            if !names.insert(r.point.name.as_str()) {
                return Err(TableError::DuplicateName(r.point.name.clone()));
            }
            if !(r.ms.is_finite() && r.ms > 0.0) {
                return Err(invalid(format!(
                    "time {} ms is not a positive number",
                    r.ms
                )));
            }
            if !r.psnr.is_finite() {
                return Err(invalid(format!("PSNR {} is not a number", r.psnr)));
            }
            if r.point.pairs != 1 {
                return Err(invalid(format!(
                    "{} pairs per bin: the node runs a bin's first pair only",
                    r.point.pairs
                )));
            }
            // The point's own rules (name, method, scale), as `bench pareto` checks them.
            r.point.check().map_err(|e| invalid(e.to_string()))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(name: &str, ms: f64, psnr: f64) -> TableRow {
        TableRow {
            point: crate::pipeline::operating::parse_points(&format!(
                "[[point]]\nname = \"{name}\""
            ))
            .unwrap()
            .remove(0),
            ms,
            psnr,
        }
    }

    #[test]
    fn rows_are_kept_most_accurate_first_and_round_trip() {
        let t = OperatingTable::new(
            (1408, 376),
            "test".into(),
            vec![
                row("fast", 100.0, 20.0),
                row("best", 900.0, 24.0),
                row("mid", 400.0, 22.0),
                row("mid-slow", 500.0, 22.0),
            ],
        )
        .unwrap();
        let names: Vec<_> = t.rows.iter().map(|r| r.point.name.as_str()).collect();
        assert_eq!(names, ["best", "mid", "mid-slow", "fast"]);
        assert_eq!(t.fastest(), 3);
        let back = OperatingTable::parse(&t.to_json(), Path::new("t.json")).unwrap();
        assert_eq!(back, t);
    }

    #[test]
    fn a_bench_pareto_report_reads_as_a_table() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let path = root.join("results/pareto/pareto.json");
        let t = OperatingTable::load(&path).unwrap();
        assert_eq!(t.size, (272, 72));
        assert!(t.rows.len() >= 15, "{}", t.rows.len());
        // tiny-pairs2 runs two pairs per bin, which the node's worker does not.
        assert!(t.rows.iter().all(|r| r.point.name != "tiny-pairs2"));
        assert!(t.rows.windows(2).all(|w| w[0].psnr >= w[1].psnr));
    }

    #[test]
    fn bad_tables_are_typed_errors() {
        let p = Path::new("t.json");
        let table = |rows: Vec<TableRow>| OperatingTable::new((10, 10), String::new(), rows);
        assert!(matches!(table(vec![]), Err(TableError::Empty)));
        assert!(matches!(
            table(vec![row("a", 1.0, 1.0), row("a", 2.0, 2.0)]),
            Err(TableError::DuplicateName(n)) if n == "a"
        ));
        for (ms, psnr) in [
            (0.0, 20.0),
            (-1.0, 20.0),
            (f64::NAN, 20.0),
            (f64::INFINITY, 20.0),
            (1.0, f64::NAN),
            (1.0, f64::NEG_INFINITY),
        ] {
            assert!(
                matches!(
                    table(vec![row("a", ms, psnr)]),
                    Err(TableError::Invalid { .. })
                ),
                "{ms} {psnr}"
            );
        }
        let mut two = row("two", 1.0, 1.0);
        two.point.pairs = 2;
        assert!(
            matches!(table(vec![two]), Err(TableError::Invalid { what, .. }) if what.contains("first pair"))
        );
        assert!(matches!(
            OperatingTable::parse("{}", p),
            Err(TableError::Syntax { .. })
        ));
        assert!(matches!(
            OperatingTable::parse("not json", p),
            Err(TableError::Syntax { .. })
        ));
        assert!(matches!(
            OperatingTable::load(Path::new("/nonexistent/table.json")),
            Err(TableError::Io { .. })
        ));
    }
}
