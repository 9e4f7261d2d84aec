//! `stereosplat bench view`: how the live view's page fares with a large map, as JSON on
//! stdout. Serves a saved map (`view --map`) on loopback and opens the page in headless
//! Chromium (`view/frame_time.mjs`) three times from the same camera: loading every tile
//! (what a page that loads the whole map draws); loading the tiles near its camera within
//! the page's default radius and a fixed Gaussian budget; and the page as it opens by
//! default, its budget following its frame time. Reports for each the load time, the
//! Gaussians drawn and the frame times, and the ratio of the median frame times.
//!
//! The camera looks straight down from [`ALTITUDE_M`] above the tile holding the most
//! Gaussians, so both runs draw the densest ground of the map.

use std::collections::HashMap;
use std::path::PathBuf;
use std::process::Command;

use anyhow::{bail, Context, Result};
use clap::Args;
use glam::DVec3;
use serde_json::{json, Value};

use crate::cli::view::saved_view_gaussians;
use crate::view::{default_node_modules, ground_tile, Bound, ViewConfig, ViewState};

/// Height of the camera above the densest tile's mean height, metres.
pub const ALTITUDE_M: f64 = 60.0;

/// Flags of `bench view`.
#[derive(Args, Clone, Debug)]
pub struct BenchViewArgs {
    /// The map: a folder `run --out` or `bench drive` wrote, or a PLY, SPZ or glTF binary file.
    #[arg(long, default_value = "out/bench_drive/map")]
    map: PathBuf,
    /// Seconds of frames recorded per run.
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    /// Tiles the page loads around its camera in the near-tiles run, metres.
    #[arg(long, default_value_t = crate::view::DEFAULT_RADIUS_M)]
    radius_m: f64,
    /// Gaussians the page loads at most in the near-tiles run, and the adaptive run's ceiling.
    #[arg(long, default_value_t = crate::view::DEFAULT_BUDGET)]
    budget: usize,
    /// The page's frame-time target in the adaptive run, milliseconds (the page's default).
    #[arg(long, default_value_t = 100.0)]
    frame_ms: f64,
    /// Seconds the adaptive page's budget must hold still before its frames are recorded.
    #[arg(long, default_value_t = 30.0)]
    settle_s: f64,
    /// Side of the view's tiles, metres.
    #[arg(long, default_value_t = 64.0)]
    tile_m: f64,
    /// The Chromium executable.
    #[arg(long, default_value = "/usr/bin/chromium")]
    chromium: PathBuf,
}

/// Runs both page loads and prints the JSON.
pub fn run(args: &BenchViewArgs) -> Result<()> {
    let gaussians = saved_view_gaussians(&args.map)?;
    let total = gaussians.len();
    let (centre, z) = densest_tile(&gaussians, args.tile_m).context("the map is empty")?;
    let state = ViewState::saved(gaussians, args.tile_m).context("the map is empty")?;
    let origin = state.origin().context("the map is empty")?;
    let eye = DVec3::new(centre.x, centre.y, z + ALTITUDE_M) - origin;
    // Looking down: camera x along world x, y along -y, z (forward) along -z.
    let rows = [1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0];
    let pose: Vec<String> = rows
        .iter()
        .chain(eye.to_array().iter())
        .map(|v| v.to_string())
        .collect();
    let pinhole = "600,600,480,270,960,540";

    let runtime = tokio::runtime::Runtime::new()?;
    let config = ViewConfig {
        bind: ([127, 0, 0, 1], 0).into(),
        node_modules: default_node_modules(),
    };
    let view =
        runtime.block_on(async { anyhow::Ok(Bound::bind(&config).await?.serve_saved(state)) })?;
    let url = view.url();
    let page = |radius: f64, budget: usize, frame_ms: f64| -> Result<Value> {
        let script = default_node_modules().with_file_name("frame_time.mjs");
        let out = Command::new("node")
            .arg(&script)
            .args([
                "--url",
                &url,
                "--pinhole",
                pinhole,
                "--pose",
                &pose.join(","),
            ])
            .args([
                "--radius",
                &radius.to_string(),
                "--budget",
                &budget.to_string(),
            ])
            .args(["--seconds", &args.seconds.to_string()])
            .args(["--frame-ms", &frame_ms.to_string()])
            .args(["--settle", &args.settle_s.to_string()])
            .arg("--chromium")
            .arg(&args.chromium)
            .output()
            .with_context(|| format!("running node {}", script.display()))?;
        let stdout = String::from_utf8_lossy(&out.stdout);
        let line = stdout.lines().last().unwrap_or("");
        let report: Value = serde_json::from_str(line).with_context(|| {
            format!(
                "frame_time.mjs printed {stdout:?}; stderr {}",
                String::from_utf8_lossy(&out.stderr)
            )
        })?;
        if report["ok"] != json!(true) {
            bail!("frame_time.mjs: {report}");
        }
        Ok(report)
    };
    let whole = page(crate::view::MAX_RADIUS_M, crate::view::MAX_BUDGET, 0.0)?;
    let near = page(args.radius_m, args.budget, 0.0)?;
    let adaptive = page(args.radius_m, args.budget, args.frame_ms)?;
    runtime.block_on(view.stop());
    let median = |v: &Value| v["frame_ms_median"].as_f64().unwrap_or(f64::NAN);
    let report = json!({
        "map": args.map,
        "gaussians": total,
        "camera": { "pinhole": pinhole, "above_densest_tile_m": ALTITUDE_M },
        "every_tile": whole,
        "near_tiles": { "radius_m": args.radius_m, "budget": args.budget, "page": near },
        "adaptive": {
            "radius_m": args.radius_m, "budget_cap": args.budget, "frame_ms": args.frame_ms,
            "page": adaptive,
        },
        "median_frame_ratio_every_to_near": median(&whole) / median(&near),
        "median_frame_ratio_near_to_adaptive": median(&near) / median(&adaptive),
    });
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}

/// The centre of the `side`-metre ground tile holding the most Gaussians, and their mean
/// height (`None` for no Gaussian).
fn densest_tile(gaussians: &[crate::fusion::WorldGaussian], side: f64) -> Option<(DVec3, f64)> {
    let mut tiles: HashMap<(i64, i64), (usize, f64)> = HashMap::new();
    for g in gaussians.iter().filter(|g| g.position.is_finite()) {
        let entry = tiles.entry(ground_tile(g.position, side)).or_default();
        entry.0 += 1;
        entry.1 += g.position.z;
    }
    let (key, (n, z)) = tiles.into_iter().max_by_key(|(k, (n, _))| (*n, *k))?;
    let centre = DVec3::new(
        (key.0 as f64 + 0.5) * side,
        (key.1 as f64 + 0.5) * side,
        0.0,
    );
    Some((centre, z / n as f64))
}
