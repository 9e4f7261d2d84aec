//! `stereosplat bench render`: rasterizer speed, as JSON on stdout.
//!
//! Times whole calls: the CPU forward pass, the CPU backward pass (loss = sum of RGB), and the
//! wgpu forward pass including upload and read-back of every output image, so the figure is
//! what a caller of `GpuRasterizer::render` waits for. Warm-up runs are not counted. The wgpu
//! frame is then split by `render_profiled` (median of the same number of runs): upload,
//! projection with its count read-back, the kernels after it and the image read-back, each
//! waited for, plus per-stage GPU timestamps where the adapter writes them.

use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use renderer::cpu::{self, OutputGrads};
use renderer::gpu::{FrameProfile, GpuRasterizer};
use renderer::RenderSettings;
use serde::Serialize;

use crate::cli::common::scene_source::SceneArgs;

/// Flags of `bench render`.
#[derive(Args, Clone, Debug)]
pub struct BenchRenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Timed runs per measurement (after warm-up).
    #[arg(long, default_value_t = 20)]
    runs: usize,
    /// Untimed runs first (caches, pipeline compilation, buffer growth).
    #[arg(long, default_value_t = 2)]
    warmup: usize,
    /// Skip the CPU rasterizer.
    #[arg(long)]
    no_cpu: bool,
    /// Skip the CPU backward pass.
    #[arg(long)]
    no_backward: bool,
    /// Skip the wgpu rasterizer.
    #[arg(long)]
    no_gpu: bool,
}

/// Milliseconds per call over the timed runs.
#[derive(Serialize)]
struct Timing {
    median_ms: f64,
    min_ms: f64,
    runs: usize,
}

#[derive(Serialize)]
struct CpuReport {
    threads: usize,
    forward: Timing,
    backward: Option<Timing>,
}

#[derive(Serialize)]
struct GpuReport {
    adapter: String,
    backend: String,
    device_type: String,
    forward: Timing,
    /// The frame split into phases and stages (medians over the timed runs).
    profile: ProfileReport,
    /// Largest absolute RGB difference from the CPU render of the same frame (when both ran).
    max_abs_rgb_diff_vs_cpu: Option<f32>,
}

#[derive(Serialize)]
struct Report {
    gaussians: usize,
    visible_gaussians: usize,
    tile_intersections: usize,
    width: u32,
    height: u32,
    cpu: Option<CpuReport>,
    gpu: Option<GpuReport>,
}

/// Medians of profiled frames, milliseconds.
#[derive(Serialize)]
struct ProfileReport {
    upload_ms: f64,
    project_and_count_readback_ms: f64,
    kernels_ms: f64,
    readback_ms: f64,
    /// GPU timestamps per stage, in order (empty where the adapter has none).
    stages: Vec<(String, f64)>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Renders `runs` profiled frames and reports each phase's and stage's median.
fn profile(
    gpu: &mut GpuRasterizer,
    set: &renderer::GaussianSet,
    cam: &renderer::Camera,
    settings: &RenderSettings,
    runs: usize,
) -> Result<ProfileReport> {
    let frames = (0..runs.max(1))
        .map(|_| Ok(gpu.render_profiled(set, cam, settings)?.1))
        .collect::<Result<Vec<FrameProfile>>>()?;
    let of = |f: fn(&FrameProfile) -> f64| median(frames.iter().map(f).collect());
    let stages = frames[0]
        .stages
        .iter()
        .enumerate()
        .map(|(i, (name, _))| {
            let times = frames.iter().filter_map(|f| f.stages.get(i).map(|s| s.1));
            (name.to_string(), median(times.collect()))
        })
        .collect();
    Ok(ProfileReport {
        upload_ms: of(|f| f.upload_ms),
        project_and_count_readback_ms: of(|f| f.project_ms),
        kernels_ms: of(|f| f.kernels_ms),
        readback_ms: of(|f| f.readback_ms),
        stages,
    })
}

fn time(warmup: usize, runs: usize, mut f: impl FnMut() -> Result<()>) -> Result<Timing> {
    for _ in 0..warmup {
        f()?;
    }
    let mut ms = Vec::with_capacity(runs);
    for _ in 0..runs.max(1) {
        let t0 = Instant::now();
        f()?;
        ms.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    Ok(Timing {
        min_ms: ms.iter().copied().fold(f64::INFINITY, f64::min),
        runs: ms.len(),
        median_ms: median(ms),
    })
}

/// Runs the benchmark and prints its JSON report.
pub fn run(args: &BenchRenderArgs) -> Result<()> {
    let cam = args.scene.camera()?;
    let set = args.scene.gaussians(&cam)?;
    let view = set.view()?;
    let params = cam.params::<f32>();
    let settings = RenderSettings::default();
    let reference = cpu::render(&view, &params, &settings);

    let cpu = if args.no_cpu {
        None
    } else {
        let forward = time(args.warmup, args.runs, || {
            std::hint::black_box(cpu::render(&view, &params, &settings));
            Ok(())
        })?;
        let backward = if args.no_backward {
            None
        } else {
            let ones = vec![1.0f32; reference.output.rgb.len()];
            let grads = OutputGrads {
                rgb: Some(&ones),
                ..Default::default()
            };
            Some(time(args.warmup, args.runs, || {
                std::hint::black_box(cpu::backward(&view, &params, &settings, &reference, &grads));
                Ok(())
            })?)
        };
        Some(CpuReport {
            threads: rayon::current_num_threads(),
            forward,
            backward,
        })
    };

    let gpu = if args.no_gpu {
        None
    } else {
        let mut gpu = GpuRasterizer::new()
            .context("no wgpu adapter (install Mesa's lavapipe: docs/ci.md, \"Steps\")")?;
        let info = gpu.adapter_info().clone();
        let forward = time(args.warmup, args.runs, || {
            std::hint::black_box(gpu.render(&set, &cam, &settings)?);
            Ok(())
        })?;
        let profile = profile(&mut gpu, &set, &cam, &settings, args.runs)?;
        let out = gpu.render(&set, &cam, &settings)?;
        let diff = out
            .rgb
            .iter()
            .zip(&reference.output.rgb)
            .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
        Some(GpuReport {
            adapter: info.name,
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            forward,
            profile,
            max_abs_rgb_diff_vs_cpu: Some(diff),
        })
    };

    let report = Report {
        gaussians: set.len(),
        visible_gaussians: reference.projected.iter().flatten().count(),
        tile_intersections: reference.bins.ids.len(),
        width: cam.intrinsics.width,
        height: cam.intrinsics.height,
        cpu,
        gpu,
    };
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}
