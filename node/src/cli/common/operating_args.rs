//! The flags that give the node a latency budget (`--latency-budget`, `--operating-points`,
//! `--calibrate`), shared by `run` and the node benchmarks, and the calibration that
//! measures a table of operating points on this machine (docs/keeping-up.md).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use model::bins::{BinConfig, BinLayout};
use model::eval::{EvalConfig, Raster};
use model::generate::VALIDATION_SEED_BASE;
use model::kitti360::Sequence;
use model::synth::SynthConfig;

use super::drives::cached_drive;
use crate::pareto::measure_points;
use crate::pipeline::operating::load_points;
use crate::pipeline::operating::{
    Budget, GovernorConfig, OperatingConfig, OperatingTable, TableRow,
};

/// The table `--calibrate` writes into the node's out folder.
pub const TABLE_FILE: &str = "operating_points.json";

/// The shipped table, measured on the project's reference machine.
pub const SHIPPED_TABLE: &str = "launch/operating_points.json";

/// The seed of the calibration's generated validation drive (validation seeds start at
/// [`VALIDATION_SEED_BASE`], disjoint from training and held-out evaluation).
const CALIBRATION_SEED: u64 = VALIDATION_SEED_BASE + 500;

/// Flags of the latency budget and its operating points.
#[derive(Args, Clone, Debug, Default)]
#[command(next_help_heading = "Latency budget")]
pub struct OperatingArgs {
    /// Choose each bin's operating point so that the worker's time per bin stays within
    /// this budget: milliseconds, or `auto` (the time between bins at the current speed).
    /// The points come from --operating-points; each bin's point is in its latency message.
    #[arg(long, value_name = "MS|auto")]
    pub latency_budget: Option<Budget>,
    /// The table of operating points (JSON, docs/keeping-up.md: `--calibrate` writes one,
    /// and a `bench pareto` report reads as one). Default: `<out>/operating_points.json`
    /// when it exists, else launch/operating_points.json.
    #[arg(long)]
    pub operating_points: Option<PathBuf>,
    /// Before the node starts, measure each point of --calibrate-points on a generated
    /// validation drive at --calibrate-size (time and PSNR) and write the table to
    /// `<out>/operating_points.json`; without --latency-budget, stop there.
    #[arg(long)]
    pub calibrate: bool,
    /// The points --calibrate measures (TOML, as `bench pareto` takes).
    #[arg(long, default_value = "launch/operating_points.toml")]
    pub calibrate_points: PathBuf,
    /// The frame size --calibrate measures at, WIDTHxHEIGHT (the size the node will see).
    #[arg(long, default_value = "1408x376", value_parser = parse_size)]
    pub calibrate_size: (u32, u32),
    /// Validation bins --calibrate measures each point on.
    #[arg(long, default_value_t = 3)]
    pub calibrate_bins: usize,
}

/// `WIDTHxHEIGHT`, both positive.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}`: give WIDTHxHEIGHT, e.g. 1408x376");
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    match (w.trim().parse::<u32>(), h.trim().parse::<u32>()) {
        (Ok(w), Ok(h)) if w >= 8 && h >= 8 && w <= 8192 && h <= 8192 => Ok((w, h)),
        _ => Err(bad()),
    }
}

impl OperatingArgs {
    /// What the node chooses its points with (`None`: no budget, one point), calibrating
    /// first into `out` when asked.
    pub fn operating(&self, out: &Path) -> Result<Option<OperatingConfig>> {
        let calibrated = match self.calibrate {
            true => {
                let table = self.calibrate(out)?;
                let path = out.join(TABLE_FILE);
                std::fs::create_dir_all(out)
                    .with_context(|| format!("creating {}", out.display()))?;
                std::fs::write(&path, table.to_json())
                    .with_context(|| format!("writing {}", path.display()))?;
                eprintln!(
                    "calibrated {} operating points: {}",
                    table.rows.len(),
                    path.display()
                );
                Some(table)
            }
            false => None,
        };
        let Some(budget) = self.latency_budget else {
            if self.operating_points.is_some() {
                bail!("--operating-points needs --latency-budget (milliseconds or auto)");
            }
            return Ok(None);
        };
        let table = match calibrated {
            Some(t) => t,
            None => {
                let path = self.operating_points.clone().unwrap_or_else(|| {
                    let own = out.join(TABLE_FILE);
                    match own.is_file() {
                        true => own,
                        false => PathBuf::from(SHIPPED_TABLE),
                    }
                });
                OperatingTable::load(&path)?
            }
        };
        Ok(Some(OperatingConfig {
            table,
            budget,
            governor: GovernorConfig::default(),
        }))
    }

    /// The table of --calibrate-points measured at --calibrate-size: each point through the
    /// worker's path on the bins of a generated validation street drive (kept in
    /// `<out>/calibration/`), its median time and bin-average PSNR.
    pub fn calibrate(&self, out: &Path) -> Result<OperatingTable> {
        let points = load_points(&self.calibrate_points)?;
        let (width, height) = self.calibrate_size;
        let bins = self.calibrate_bins.max(1);
        let stride = 10;
        let synth = SynthConfig {
            seed: CALIBRATION_SEED,
            frames: (stride * bins + 12) as u32,
            width,
            height,
            ..SynthConfig::default()
        };
        let root = out.join("calibration");
        let name = cached_drive(&root, &synth)?;
        let sequence = Sequence::open(&root, &name)?;
        let mut config = EvalConfig {
            bins: BinConfig {
                length_m: 8.0,
                layout: BinLayout::Sliding { stride },
            },
            max_bins: Some(bins),
            picture_bins: 0,
            lpips: None,
            ..EvalConfig::default()
        };
        let measured = measure_points(&points, &sequence, &mut Raster::Cpu, &mut config, 8.0)?;
        let rows = measured
            .points
            .into_iter()
            .filter(|p| p.point.pairs == 1 && p.latency_median_ms.is_finite())
            .map(|p| TableRow {
                point: p.point,
                ms: p.latency_median_ms,
                psnr: p.psnr,
            })
            .collect();
        let source = format!(
            "run --calibrate: {} on {bins} bins of the generated validation street drive \
             (seed {CALIBRATION_SEED}) at {width}x{height}, {} threads",
            self.calibrate_points.display(),
            rayon::current_num_threads()
        );
        Ok(OperatingTable::new((width, height), source, rows)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_bad_ones_are_refused() {
        assert_eq!(parse_size("1408x376"), Ok((1408, 376)));
        for bad in ["1408", "x376", "0x10", "10x0", "-4x8", "99999x8", "axb", ""] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_budget_reads_its_table_and_a_table_without_a_budget_is_refused() {
        let out = Path::new("/nonexistent/out");
        assert!(OperatingArgs::default().operating(out).unwrap().is_none());
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join(SHIPPED_TABLE);
        let table_only = OperatingArgs {
            operating_points: Some(shipped.clone()),
            ..OperatingArgs::default()
        };
        let err = table_only.operating(out).unwrap_err().to_string();
        assert!(err.contains("--latency-budget"), "{err}");
        let with_budget = OperatingArgs {
            latency_budget: Some(Budget::Auto),
            operating_points: Some(shipped),
            ..OperatingArgs::default()
        };
        let o = with_budget.operating(out).unwrap().unwrap();
        assert_eq!(o.budget, Budget::Auto);
        assert_eq!(o.table.size, (1408, 376));
        let missing = OperatingArgs {
            latency_budget: Some(Budget::Fixed(800.0)),
            operating_points: Some(PathBuf::from("/nonexistent/table.json")),
            ..OperatingArgs::default()
        };
        assert!(missing.operating(out).is_err());
    }

    #[test]
    fn the_shipped_table_and_points_list_name_points_that_load() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let table = OperatingTable::load(&root.join(SHIPPED_TABLE)).unwrap();
        let listed = load_points(&root.join("launch/operating_points.toml")).unwrap();
        assert_eq!(table.rows.len(), listed.len());
        for row in &table.rows {
            assert!(listed.contains(&row.point), "{}", row.point.name);
            assert_eq!(
                row.point.availability(),
                crate::pipeline::operating::Availability::Ready
            );
        }
    }

    #[test]
    fn budgets_parse_and_bad_ones_are_refused() {
        assert_eq!("auto".parse::<Budget>(), Ok(Budget::Auto));
        assert_eq!("800".parse::<Budget>(), Ok(Budget::Fixed(800.0)));
        for bad in ["0", "-5", "nan", "inf", "fast", ""] {
            assert!(bad.parse::<Budget>().is_err(), "{bad}");
        }
    }
}
