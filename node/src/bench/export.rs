//! `stereosplat bench export`: size and speed of each map format for one map, as JSON on
//! stdout. For PLY, SPZ and glTF binary in turn: the bytes written, and the median time of
//! writing the map into memory and of reading it back, over `--runs` runs after one untimed
//! run (file-system time is left out, it belongs to the disk, not the format).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;
use renderer::formats::{read_map, write_map, MapFormat};

use crate::cli::export::load_input;

/// Flags of `bench export`.
#[derive(Args, Clone, Debug)]
pub struct BenchExportArgs {
    /// The map: a PLY, SPZ or glTF binary file, or a node checkpoint (`global_map.ssgmap`,
    /// exported around its latest bin as `run` does).
    #[arg(long, default_value = "out/demo/map/global_map.ssgmap")]
    map: PathBuf,
    /// Timed runs per format (the median is reported).
    #[arg(long, default_value_t = 5)]
    runs: usize,
}

/// Median of `samples`, milliseconds.
fn median_ms(mut samples: Vec<f64>) -> f64 {
    samples.sort_by(f64::total_cmp);
    samples.get(samples.len() / 2).copied().unwrap_or(f64::NAN) * 1e3
}

/// Measures every format and prints the JSON.
pub fn run(args: &BenchExportArgs) -> Result<()> {
    let input = load_input(&args.map)?;
    let set = &input.set;
    let runs = args.runs.max(1);
    let mut rows = Vec::new();
    let mut ply_bytes = 0;
    for format in MapFormat::ALL {
        let mut bytes = Vec::new();
        let exported = write_map(set, format, &mut bytes)?;
        let (mut write_s, mut read_s) = (Vec::new(), Vec::new());
        for _ in 0..runs {
            let mut out = Vec::with_capacity(bytes.len());
            let t = Instant::now();
            write_map(set, format, &mut out)?;
            write_s.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            let (_, back) = read_map(out.as_slice())?;
            read_s.push(t.elapsed().as_secs_f64());
            anyhow::ensure!(
                back.len() == exported.gaussians,
                "{format}: read back {}",
                back.len()
            );
        }
        if format == MapFormat::Ply {
            ply_bytes = bytes.len();
        }
        rows.push(serde_json::json!({
            "format": format.to_string(),
            "bytes": bytes.len(),
            "bytes_per_gaussian": bytes.len() as f64 / exported.gaussians.max(1) as f64,
            "size_vs_ply": bytes.len() as f64 / ply_bytes.max(1) as f64,
            "write_ms": median_ms(write_s),
            "read_ms": median_ms(read_s),
            "max_position_error_m": exported.max_position_error_m,
            "skipped_non_finite": exported.skipped_non_finite,
        }));
    }
    let summary = serde_json::json!({
        "map": args.map,
        "input_kind": input.kind,
        "gaussians": set.len(),
        "runs": runs,
        "threads": std::thread::available_parallelism().map_or(1, |n| n.get()),
        "formats": rows,
    });
    println!("{}", serde_json::to_string_pretty(&summary)?);
    Ok(())
}
