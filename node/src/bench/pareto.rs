//! `stereosplat bench pareto`, speed against accuracy as a measured trade: every operating
//! point of a TOML list (`launch/pareto.toml`) run one after another in this process on the
//! same held-out bins and scored by the evaluation protocol ([`crate::pareto`]). Writes
//! `pareto.json` (also printed on stdout), `pareto.md` and `pareto.png` into `--out`; a point
//! whose weight file is missing is skipped and listed.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use model::bins::{BinConfig, BinLayout};
use model::eval::EvalConfig;
use model::kitti360::Sequence;
use model::metrics::DepthFilter;

use crate::cli::common::drives::first_sequence;
use crate::pareto::{measure_points, ParetoReport};
use crate::pipeline::operating::load_points;
use crate::research::eval::{lpips_unless, raster_for};

/// Flags of `bench pareto`.
#[derive(Args, Clone, Debug)]
pub struct BenchParetoArgs {
    /// The operating points (TOML, see `launch/pareto.toml`).
    #[arg(long, default_value = "launch/pareto.toml")]
    points: PathBuf,
    /// Data root in the KITTI-360 layout (held-out drives: `stereosplat research synth-heldout`).
    #[arg(long)]
    data: PathBuf,
    /// The sequence (default: the root's first).
    #[arg(long)]
    seq: Option<String>,
    /// Output folder.
    #[arg(long, default_value = "out/pareto")]
    out: PathBuf,
    /// Frames between the starts of consecutive bins.
    #[arg(long, default_value_t = 10)]
    stride: usize,
    /// At most this many bins, spread evenly over the sequence.
    #[arg(long)]
    max_bins: Option<usize>,
    /// Distance between a bin's first and last frames, metres.
    #[arg(long, default_value_t = 8.0)]
    bin_length: f64,
    /// Skip LPIPS (the slowest metric).
    #[arg(long)]
    no_lpips: bool,
    /// Render the scoring views on wgpu instead of the CPU reference rasterizer.
    #[arg(long)]
    gpu: bool,
}

/// Runs every point and writes the report.
pub fn run(args: &BenchParetoArgs) -> Result<()> {
    let points = load_points(&args.points)?;
    let name = match &args.seq {
        Some(s) => s.clone(),
        None => first_sequence(&args.data)?,
    };
    let sequence = Sequence::open(&args.data, &name)?;
    let mut raster = raster_for(args.gpu)?;
    let mut config = EvalConfig {
        bins: BinConfig {
            length_m: args.bin_length,
            layout: BinLayout::Sliding {
                stride: args.stride,
            },
        },
        depth: DepthFilter::default(),
        max_bins: args.max_bins,
        picture_bins: 0,
        lpips: lpips_unless(args.no_lpips)?,
        ..EvalConfig::default()
    };
    let mut report = ParetoReport {
        data: args.data.display().to_string(),
        sequence: name.clone(),
        stride: args.stride,
        size: (
            sequence.rig().intrinsics.width,
            sequence.rig().intrinsics.height,
        ),
        raster: raster.name(),
        threads: rayon::current_num_threads(),
        peak_memory: String::new(),
        points: Vec::new(),
        skipped: Vec::new(),
    };
    let measured = measure_points(
        &points,
        &sequence,
        &mut raster,
        &mut config,
        args.bin_length,
    )?;
    report.points = measured.points;
    report.skipped = measured.skipped;
    let reset_everywhere = measured.peak_reset;
    report.peak_memory = match reset_everywhere {
        true => "the process's peak resident memory (VmHWM) during one bin's path, reset to \
                 the resident memory before every bin through /proc/self/clear_refs; it \
                 includes what the process holds besides (data, LPIPS, the point's weights) \
                 and what the allocator kept from earlier points, so only a rise over the \
                 points before is a point's own (one point per process measures it alone)"
            .into(),
        false => "the process's peak resident memory since its start (the kernel refused \
                  the per-bin reset): only growth between points is the point's own"
            .into(),
    };
    report.mark_fronts();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let json = serde_json::to_string_pretty(&report)? + "\n";
    let md = report.markdown();
    for (file, text) in [("pareto.json", &json), ("pareto.md", &md)] {
        let path = args.out.join(file);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    model::curve::scatter::write_png(&args.out.join("pareto.png"), &report.panels(), 640, 440)?;
    print!("{json}");
    eprintln!(
        "wrote {}/pareto.json, pareto.md and pareto.png",
        args.out.display()
    );
    Ok(())
}
