//! `stereosplat bench check`: the per-bin self-check (`model::consistency`) on generated
//! drives, as JSON on stdout, to choose its thresholds and to measure its cost.
//!
//! For every `--stride`-th frame of `--drives` held-out drives, each method reconstructs the
//! pair and the check scores it, on the true pair and on three bad ones: the right image of
//! another drive (`other_scene`), left and right swapped (`swapped`), the right image shifted
//! down by `--shift` pixels (`shifted`). Per method and case: the score and coverage
//! distributions (min, p10, median, p90, max), the verdict counts, and the check's time per
//! bin (median and max over every check run).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;
use model::consistency::{check, CheckSettings, Verdict};
use model::frame::{RgbImage, Side, StereoFrame};
use model::generate::VALIDATION_SEED_BASE;
use model::kitti360::Sequence;
use model::reconstruct::StereoView;
use model::synth::SynthConfig;
use serde::Serialize;
use serde_json::{json, Value};

use crate::cli::common::drives::cached_drive;

/// Flags of `bench check`.
#[derive(Args, Clone, Debug)]
pub struct BenchCheckArgs {
    /// Methods to check (`model::methods` names).
    #[arg(long, value_delimiter = ',', default_value = "sgm,stereosplat")]
    methods: Vec<String>,
    /// Drives, seeds from `--first-seed` up.
    #[arg(long, default_value_t = 2)]
    drives: u64,
    /// Seed of the first drive: the validation drives by default (the check's thresholds are
    /// chosen on them); 1000000 for the held-out ones.
    #[arg(long, default_value_t = VALIDATION_SEED_BASE)]
    first_seed: u64,
    /// Frames per drive.
    #[arg(long, default_value_t = 60)]
    frames: u32,
    /// Every this many frames is one bin's reference pair.
    #[arg(long, default_value_t = 5)]
    stride: usize,
    /// Image width.
    #[arg(long, default_value_t = 272)]
    width: u32,
    /// Image height.
    #[arg(long, default_value_t = 72)]
    height: u32,
    /// Pixels the `shifted` case moves the right image down.
    #[arg(long, default_value_t = 6)]
    shift: u32,
    /// ZNCC from which a sample counts as consistent (default: the check's setting).
    #[arg(long)]
    good_zncc: Option<f32>,
    /// Where the drives are kept between runs.
    #[arg(long, default_value = "out/bench_check")]
    cache: PathBuf,
}

/// The bad pairs (and the true one) every bin is checked on.
const CASES: [&str; 4] = ["true_pair", "other_scene", "swapped", "shifted"];

/// Scores of one method on one case.
#[derive(Default)]
struct Scores {
    score: Vec<f64>,
    coverage: Vec<f64>,
    /// Score x coverage: the share of textured cells explained, what the verdict uses.
    explained: Vec<f64>,
    verdicts: [u64; 3],
}

/// `image` moved down by `rows` (the top rows repeat the first row).
fn shifted_down(image: &RgbImage, rows: u32) -> RgbImage {
    let row = 3 * image.width as usize;
    let mut out = image.clone();
    for y in 0..image.height as usize {
        let from = y.saturating_sub(rows as usize);
        out.data[y * row..(y + 1) * row].copy_from_slice(&image.data[from * row..(from + 1) * row]);
    }
    out
}

/// min, p10, median, p90, max of `values` (nearest rank), null when empty.
fn distribution(values: &[f64]) -> Value {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let Some(&max) = v.last() else {
        return Value::Null;
    };
    let rank = |p: usize| v[(p * v.len()).div_ceil(100).max(1) - 1];
    json!({"min": v[0], "p10": rank(10), "median": rank(50), "p90": rank(90), "max": max})
}

#[derive(Serialize)]
struct Timing {
    checks: usize,
    median_ms: f64,
    max_ms: f64,
}

/// Runs the benchmark and prints its JSON report.
pub fn run(args: &BenchCheckArgs) -> Result<()> {
    let defaults = CheckSettings::default();
    let settings = CheckSettings {
        good_zncc: args.good_zncc.unwrap_or(defaults.good_zncc),
        ..defaults
    };
    let mut pairs: Vec<(StereoFrame, usize)> = Vec::new();
    let mut drives = Vec::new();
    for d in 0..args.drives.max(2) {
        let config = SynthConfig {
            seed: args.first_seed + d,
            frames: args.frames,
            width: args.width,
            height: args.height,
            ..SynthConfig::default()
        };
        let name = cached_drive(&args.cache, &config)?;
        drives.push(Sequence::open(&args.cache, &name)?);
    }
    for (d, seq) in drives.iter().enumerate() {
        for info in seq.frames().iter().step_by(args.stride.max(1)) {
            pairs.push((seq.load_frame(info.index)?, d));
        }
    }
    let mut report = serde_json::Map::new();
    let mut times = Vec::new();
    for method in &args.methods {
        let mut rec = model::methods::by_name(method)?;
        let mut per_case: Vec<Scores> = CASES.iter().map(|_| Scores::default()).collect();
        for (n, (frame, d)) in pairs.iter().enumerate() {
            let rig = drives[*d].rig();
            let pose = frame.left_to_world;
            // The right image of another bin of another drive.
            let other = &pairs[(n + pairs.len() / 2) % pairs.len()].0.right;
            let shifted = shifted_down(&frame.right, args.shift);
            let images = [
                (&frame.left, &frame.right),
                (&frame.left, other),
                (&frame.right, &frame.left),
                (&frame.left, &shifted),
            ];
            for (scores, (left, right)) in per_case.iter_mut().zip(images) {
                let view = StereoView {
                    left,
                    right,
                    left_camera: rig.local_camera(pose, pose, Side::Left),
                    right_camera: rig.local_camera(pose, pose, Side::Right),
                };
                let set = rec.reconstruct(&[view])?;
                let t0 = Instant::now();
                let r = check(&view, &set, &settings);
                times.push(t0.elapsed().as_secs_f64() * 1e3);
                scores.score.push(r.score as f64);
                scores.coverage.push(r.coverage as f64);
                scores.explained.push((r.score * r.coverage) as f64);
                let slot = match r.verdict {
                    Verdict::Pass => 0,
                    Verdict::Fail => 1,
                    Verdict::Undetermined => 2,
                };
                scores.verdicts[slot] += 1;
            }
        }
        let cases: serde_json::Map<String, Value> = CASES
            .iter()
            .zip(&per_case)
            .map(|(case, s)| {
                let v = json!({
                    "bins": s.score.len(),
                    "score": distribution(&s.score),
                    "coverage": distribution(&s.coverage),
                    "explained": distribution(&s.explained),
                    "pass": s.verdicts[0], "fail": s.verdicts[1], "undetermined": s.verdicts[2],
                });
                (case.to_string(), v)
            })
            .collect();
        report.insert(method.clone(), Value::Object(cases));
    }
    times.sort_by(f64::total_cmp);
    let timing = Timing {
        checks: times.len(),
        median_ms: times.get(times.len() / 2).copied().unwrap_or(0.0),
        max_ms: times.last().copied().unwrap_or(0.0),
    };
    let out = json!({
        "first_seed": args.first_seed, "width": args.width, "height": args.height, "drives": args.drives.max(2),
        "frames": args.frames, "stride": args.stride, "shift": args.shift,
        "settings": format!("{settings:?}"),
        "check_time": timing, "methods": report,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
