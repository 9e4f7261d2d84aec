//! `stereosplat research eval`: the paper's protocol on a data root in the KITTI-360 layout
//! (real or synthetic). Writes `eval.md` (the table), `eval.json` (every score) and pictures of
//! a few bins into the output folder, and prints the table. Frames are scored with PSNR, SSIM,
//! LPIPS (unless `--no-lpips`) and, where there is LiDAR, AbsRel and SqRel.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use model::bins::{BinConfig, BinLayout};
use model::eval::{evaluate, EvalConfig, EvalReport, Raster};
use model::kitti360::Sequence;
use model::lpips::Lpips;
use model::metrics::DepthFilter;
use renderer::gpu::GpuRasterizer;

use crate::cli::common::method_args::MethodArgs;
use crate::progress;

/// Flags of `eval`.
#[derive(Args, Clone, Debug)]
pub struct EvalArgs {
    /// Data root in the KITTI-360 layout.
    #[arg(long)]
    data: PathBuf,
    /// Only this sequence (default: every sequence under `data_2d_raw`).
    #[arg(long)]
    seq: Option<String>,
    #[command(flatten)]
    method: MethodArgs,
    /// Output folder.
    #[arg(long, default_value = "out/eval")]
    out: PathBuf,
    /// Distance between a bin's first and last frames, metres.
    #[arg(long, default_value_t = 8.0)]
    bin_length: f64,
    /// Frames between the starts of consecutive bins (1: a bin per frame, as the paper).
    #[arg(long, default_value_t = 1)]
    stride: usize,
    /// At most this many bins per sequence, spread evenly over it.
    #[arg(long)]
    max_bins: Option<usize>,
    /// Bins per sequence that get pictures.
    #[arg(long, default_value_t = 3)]
    pictures: usize,
    /// LiDAR depths beyond this many metres do not count (KITTI convention: 80).
    #[arg(long, default_value_t = DepthFilter::default().max_depth)]
    max_depth: f32,
    /// Load frames at this size (intrinsics scaled), e.g. to run real KITTI-360 at 544x144.
    #[arg(long, num_args = 2, value_names = ["WIDTH", "HEIGHT"])]
    resize: Option<Vec<u32>>,
    /// Render on wgpu instead of the CPU reference rasterizer.
    #[arg(long)]
    gpu: bool,
    /// Input stereo pairs per bin, its first frames (the paper's protocol: 1).
    #[arg(long, default_value_t = 1)]
    pairs: usize,
    /// Skip LPIPS (AlexNet on the CPU, the slowest metric); the table loses its LPIPS columns.
    #[arg(long)]
    no_lpips: bool,
}

/// Runs the evaluation and writes the report.
pub fn run(args: &EvalArgs) -> Result<()> {
    let names = match &args.seq {
        Some(s) => vec![s.clone()],
        None => Sequence::list(&args.data)
            .with_context(|| format!("listing sequences in {}", args.data.display()))?,
    };
    let mut reconstructor = args.method.build()?;
    let mut raster = raster_for(args.gpu)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let lpips = lpips_unless(args.no_lpips)?;
    let config = EvalConfig {
        bins: BinConfig {
            length_m: args.bin_length,
            layout: BinLayout::Sliding {
                stride: args.stride,
            },
        },
        depth: DepthFilter {
            max_depth: args.max_depth,
            ..DepthFilter::default()
        },
        max_bins: args.max_bins,
        picture_bins: args.pictures,
        picture_dir: Some(args.out.join("pictures")),
        lpips,
        input_pairs: args.pairs,
        ..EvalConfig::default()
    };
    let (mut bins, mut skipped) = (Vec::new(), Vec::new());
    for name in &names {
        let mut sequence = Sequence::open(&args.data, name)?;
        if let Some(size) = &args.resize {
            sequence = sequence.with_resolution(size[0], size[1]);
        }
        let bar = progress::bar(0, name);
        let (b, s) = evaluate(
            &sequence,
            reconstructor.as_mut(),
            &mut raster,
            &config,
            &mut progress::hook(&bar),
        )?;
        bar.finish_and_clear();
        bins.extend(b);
        skipped.extend(s);
    }
    let report = EvalReport::new(
        reconstructor.name().to_string(),
        raster.name(),
        args.bin_length,
        (config.depth.min_depth, config.depth.max_depth),
        bins,
        skipped,
    );
    let md = report.markdown();
    for (name, text) in [
        ("eval.md", md.clone()),
        ("eval.json", serde_json::to_string_pretty(&report)?),
    ] {
        let path = args.out.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    println!("{md}");
    println!(
        "wrote {}/eval.md, eval.json and pictures/",
        args.out.display()
    );
    Ok(())
}

/// The rasterizer of the scoring renders: wgpu when `gpu`, else the CPU reference.
pub fn raster_for(gpu: bool) -> Result<Raster> {
    Ok(match gpu {
        true => Raster::Gpu(Box::new(GpuRasterizer::new().context("no wgpu adapter")?)),
        false => Raster::Cpu,
    })
}

/// The LPIPS network, unless `skip` (LPIPS is the slowest metric).
pub fn lpips_unless(skip: bool) -> Result<Option<Lpips>> {
    match skip {
        true => Ok(None),
        false => Ok(Some(
            Lpips::load_default().context("loading the LPIPS weights")?,
        )),
    }
}
