//! `stereosplat research eval-map`: the fused global map's own quality on a drive
//! ([`crate::research::map_quality`]), swept over the fusion's settings one at a time around
//! the node's defaults (map budget, cell size, keep range, keep confidence). Writes
//! `eval_map.json`, `eval_map.md` (Gaussians in the map and per metre of drive against PSNR,
//! SSIM, LPIPS, AbsRel, SqRel at every frame's camera), `eval_map.png` (the sweep against the
//! map's size, the front marked: no other setting both smaller and better), bird's-eye views of
//! the map fusing everything and with the default keep rule, and renders from beside the
//! trajectory.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use glam::DVec2;
use model::curve::scatter::{self, Panel, ScatterPoint};
use model::eval::{EvalConfig, MeanScores};
use model::kitti360::images::write_png;
use model::kitti360::Sequence;
use serde::Serialize;

use super::eval::{lpips_unless, raster_for};
use crate::cli::common::drives::first_sequence;
use crate::cli::common::method_args::MethodArgs;
use crate::fusion::{bev_image, save_bev_png, BevView, FusionConfig, GlobalMap, Keep};
use crate::pareto::{front, front_mark, table_cell, Better};
use crate::pipeline::self_check::OnCheckFail;
use crate::progress;
use crate::research::map_quality::{bin_maps, fuse, score_map, side_view, Backdrops, MapScores};

/// Flags of `eval-map`.
#[derive(Args, Clone, Debug)]
pub struct EvalMapArgs {
    /// Data root in the KITTI-360 layout.
    #[arg(long)]
    data: PathBuf,
    /// The sequence (default: the root's first).
    #[arg(long)]
    seq: Option<String>,
    #[command(flatten)]
    method: MethodArgs,
    /// Output folder.
    #[arg(long, default_value = "out/eval_map")]
    out: PathBuf,
    /// Bin length, metres (the node's binner).
    #[arg(long, default_value_t = 8.0)]
    bin_length: f64,
    /// Render the map at every n-th frame.
    #[arg(long, default_value_t = 2)]
    frame_stride: usize,
    /// Map budgets to sweep (Gaussians).
    #[arg(long, value_delimiter = ',', default_values_t = [100_000usize, 40_000, 15_000])]
    budgets: Vec<usize>,
    /// Cell sizes to sweep, metres.
    #[arg(long, value_delimiter = ',', default_values_t = [0.1f64, 0.5, 1.0])]
    cell_sizes: Vec<f64>,
    /// Keep ranges to sweep, metres (`inf`: fuse every distance, the map before the rule).
    #[arg(long, value_delimiter = ',', default_values_t = [f32::INFINITY, 80.0, 20.0])]
    ranges: Vec<f32>,
    /// Keep ranges to score again with each bin's sky layer (its Gaussians beyond the range)
    /// drawn behind the map at the bin's frames, as a consumer rendering views would.
    #[arg(long, value_delimiter = ',', default_values_t = [40.0f32, 30.0, 20.0])]
    sky_ranges: Vec<f32>,
    /// Keep confidence floors to sweep.
    #[arg(long, value_delimiter = ',', default_values_t = [0.3f32])]
    confidences: Vec<f32>,
    /// Skip LPIPS.
    #[arg(long)]
    no_lpips: bool,
    /// Render on wgpu instead of the CPU reference rasterizer.
    #[arg(long)]
    gpu: bool,
}

/// One fusion setting's map and scores.
#[derive(Serialize)]
struct Row {
    setting: String,
    cell_size: f64,
    max_gaussians: usize,
    keep_max_range_m: f32,
    keep_min_confidence: f32,
    /// Mean Gaussians of the sky layer drawn behind the map (one bin's far part), when the
    /// row draws it.
    sky_layer_gaussians: Option<f64>,
    gaussians: usize,
    gaussians_per_metre: f64,
    scores: MapScores,
    front_psnr: bool,
    front_abs_rel: bool,
}

/// Runs the sweep and writes the report.
pub fn run(args: &EvalMapArgs) -> Result<()> {
    let name = match &args.seq {
        Some(s) => s.clone(),
        None => first_sequence(&args.data)?,
    };
    let sequence = Sequence::open(&args.data, &name)?;
    let mut reconstructor = args.method.build()?;
    let mut raster = raster_for(args.gpu)?;
    let config = EvalConfig {
        lpips: lpips_unless(args.no_lpips)?,
        ..EvalConfig::default()
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;

    let bar = progress::bar(0, "bin maps");
    let (maps, length_m) = bin_maps(
        &sequence,
        reconstructor.as_mut(),
        args.bin_length,
        OnCheckFail::default(),
        &mut progress::hook(&bar),
    )?;
    bar.finish_and_clear();

    let mut rows = Vec::new();
    for (setting, fusion, sky) in settings(args) {
        let map = fuse(&maps, fusion)?;
        let bar = progress::bar(0, &setting);
        let backdrops = sky.then(|| Backdrops::new(&maps, fusion.keep));
        let sky_layer_gaussians = backdrops.as_ref().map(Backdrops::mean_len);
        let scores = score_map(
            &map,
            backdrops.as_ref(),
            &sequence,
            &mut raster,
            &config,
            args.frame_stride,
            &mut progress::hook(&bar),
        )?;
        bar.finish_and_clear();
        eprintln!(
            "{setting:>16}: {} Gaussians, PSNR {:.2}, AbsRel {:.4}",
            map.len(),
            scores.mean.psnr,
            scores.mean.abs_rel.unwrap_or(f64::NAN)
        );
        if setting == "default" || (setting.starts_with("range") && !sky) {
            pictures(args, &map, &sequence, &mut raster, &config, &setting)?;
        }
        rows.push(Row {
            setting,
            cell_size: fusion.cell_size,
            max_gaussians: fusion.max_gaussians,
            keep_max_range_m: fusion.keep.max_range_m,
            keep_min_confidence: fusion.keep.min_confidence,
            sky_layer_gaussians,
            gaussians: map.len(),
            gaussians_per_metre: map.len() as f64 / length_m.max(1e-9),
            scores,
            front_psnr: false,
            front_abs_rel: false,
        });
    }
    let mark = |q: &dyn Fn(&MeanScores) -> f64, better| {
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| (r.gaussians as f64, q(&r.scores.mean)))
            .collect();
        front(&pts, better)
    };
    let psnr = mark(&|m| m.psnr, Better::Higher);
    let abs_rel = mark(&|m| m.abs_rel.unwrap_or(f64::NAN), Better::Lower);
    for ((r, a), b) in rows.iter_mut().zip(psnr).zip(abs_rel) {
        r.front_psnr = a;
        r.front_abs_rel = b;
    }

    let md = markdown(&name, &args.method, maps.len(), length_m, args, &rows);
    let json = serde_json::json!({
        "sequence": name,
        "method": reconstructor.name(),
        "bins": maps.len(),
        "drive_length_m": length_m,
        "frame_stride": args.frame_stride,
        "raster": raster.name(),
        "rows": rows,
    });
    for (file, text) in [
        ("eval_map.json", serde_json::to_string_pretty(&json)? + "\n"),
        ("eval_map.md", md.clone()),
    ] {
        let path = args.out.join(file);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    let panel = |title: &str, y_title: &str, y: &dyn Fn(&Row) -> (f64, bool)| Panel {
        title: title.into(),
        x_title: "Gaussians in the fused map (log scale)".into(),
        y_title: y_title.into(),
        log_x: true,
        points: rows
            .iter()
            .map(|r| {
                let (y, on_front) = y(r);
                ScatterPoint {
                    label: r.setting.clone(),
                    x: r.gaussians as f64,
                    y,
                    on_front,
                }
            })
            .collect(),
    };
    let panels = [
        panel(
            "PSNR against map size (ringed: Pareto front)",
            "fused-map PSNR, dB",
            &|r| (r.scores.mean.psnr, r.front_psnr),
        ),
        panel(
            "AbsRel against map size (ringed: Pareto front)",
            "fused-map AbsRel",
            &|r| (r.scores.mean.abs_rel.unwrap_or(f64::NAN), r.front_abs_rel),
        ),
    ];
    scatter::write_png(&args.out.join("eval_map.png"), &panels, 640, 440)?;
    println!("{md}");
    println!(
        "wrote {}/eval_map.{{md,json,png}} and pictures",
        args.out.display()
    );
    Ok(())
}

/// The node's defaults, then one setting changed at a time; the flag: draw the sky layer.
fn settings(args: &EvalMapArgs) -> Vec<(String, FusionConfig, bool)> {
    let base = FusionConfig::default();
    let mut out = vec![("default".to_string(), base, false)];
    for &b in &args.budgets {
        out.push((
            format!("budget {b}"),
            FusionConfig {
                max_gaussians: b,
                ..base
            },
            false,
        ));
    }
    for &c in &args.cell_sizes {
        out.push((
            format!("cell {c}"),
            FusionConfig {
                cell_size: c,
                ..base
            },
            false,
        ));
    }
    for &r in &args.ranges {
        let keep = Keep {
            max_range_m: r,
            ..base.keep
        };
        out.push((format!("range {r}"), FusionConfig { keep, ..base }, false));
    }
    for &r in &args.sky_ranges {
        let keep = Keep {
            max_range_m: r,
            ..base.keep
        };
        let config = FusionConfig { keep, ..base };
        out.push((format!("range {r} + sky layer"), config, true));
    }
    for &c in &args.confidences {
        let keep = Keep {
            min_confidence: c,
            ..base.keep
        };
        out.push((format!("conf {c}"), FusionConfig { keep, ..base }, false));
    }
    out
}

/// The bird's-eye view (as the node exports it: 512 px at 0.25 m, around the latest bin)
/// and renders 3 m left and right of the trajectory at three frames, beside the render on it.
fn pictures(
    args: &EvalMapArgs,
    map: &GlobalMap,
    sequence: &Sequence,
    raster: &mut model::eval::Raster,
    config: &EvalConfig,
    setting: &str,
) -> Result<()> {
    let tag = setting.replace(' ', "_");
    if let Some(origin) = map.latest_origin() {
        let view = BevView::export(DVec2::new(origin.x, origin.y));
        let img = bev_image(map.gaussians().map(|(_, g)| g), &view)?;
        save_bev_png(&img, args.out.join(format!("bev_{tag}.png")))?;
    }
    let frames = sequence.frames();
    for k in [1, 2, 3] {
        let frame = frames[k * frames.len() / 4].index;
        for (offset, side) in [(-3.0, "left3m"), (0.0, "on"), (3.0, "right3m")] {
            let img = side_view(map, sequence, raster, config, frame, offset)?;
            let path = args.out.join(format!("side_{tag}_{frame:04}_{side}.png"));
            write_png(&path, &img)?;
        }
    }
    Ok(())
}

fn markdown(
    name: &str,
    method: &MethodArgs,
    bins: usize,
    length_m: f64,
    args: &EvalMapArgs,
    rows: &[Row],
) -> String {
    let mut s = format!(
        "# The fused map's own quality\n\n`{name}`: {bins} bins of {} m over {length_m:.0} m, \
         bin maps by `{}`{}; the fused map rendered at every {} frame's left camera. \
         `*`: on the front (no other setting with fewer Gaussians and better). Sky layer: \
         mean Gaussians of the bin's far part drawn behind the map (not in it).\n\n\
         | setting | Gaussians | per metre | sky layer | PSNR | SSIM | LPIPS | AbsRel | SqRel \
         | front PSNR | front AbsRel |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|:---:|:---:|\n",
        args.bin_length,
        method.method,
        method
            .preset
            .as_ref()
            .map_or(String::new(), |p| format!(" preset `{p}`")),
        match args.frame_stride {
            1 => "".to_string(),
            n => format!("{n}th"),
        },
    );
    for r in rows {
        let m = &r.scores.mean;
        s.push_str(&format!(
            "| {} | {} | {:.0} | {} | {:.2} | {:.3} | {} | {} | {} | {} | {} |\n",
            r.setting,
            r.gaussians,
            r.gaussians_per_metre,
            r.sky_layer_gaussians
                .map_or("-".into(), |g| format!("{g:.0}")),
            m.psnr,
            m.ssim,
            table_cell(m.lpips, 3),
            table_cell(m.abs_rel, 4),
            table_cell(m.sq_rel, 3),
            front_mark(r.front_psnr),
            front_mark(r.front_abs_rel),
        ));
    }
    s
}
