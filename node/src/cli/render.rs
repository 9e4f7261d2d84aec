//! `stereosplat render`: a map (PLY, SPZ or glTF binary, or a generated scene) to PNG pictures.
//!
//! The main job of the project until the streaming node exists: with no flags it generates
//! the seeded street scene, writes it as a 3DGS PLY, and renders RGB, depth and alpha on the
//! wgpu rasterizer (the CPU reference with `--cpu`).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use renderer::gpu::GpuRasterizer;
use renderer::picture::{self, DepthScale};
use renderer::{cpu, RenderOutput, RenderSettings};

use super::common::scene_source::SceneArgs;

/// Flags of `render`.
#[derive(Args, Clone, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Output folder for the pictures (and the generated scene's PLY).
    #[arg(long, default_value = "out/render")]
    out: PathBuf,
    /// Render on the CPU reference rasterizer instead of wgpu.
    #[arg(long)]
    cpu: bool,
}

/// Renders and writes the pictures, printing where they are.
pub fn run(args: &RenderArgs) -> Result<()> {
    let cam = args.scene.camera()?;
    let set = args.scene.gaussians(&cam)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    if args.scene.map.is_none() {
        let ply = args.out.join("scene.ply");
        renderer::ply::save_ply(&set, &ply)
            .with_context(|| format!("writing {}", ply.display()))?;
        println!("scene: {} Gaussians -> {}", set.len(), ply.display());
    }
    let settings = RenderSettings::default();
    let (out, device): (RenderOutput, String) = if args.cpu {
        let params = cam.params::<f32>();
        (
            cpu::render(&set.view()?, &params, &settings).output,
            "CPU reference".into(),
        )
    } else {
        let mut gpu = GpuRasterizer::new()
            .context("no wgpu adapter (install Mesa's lavapipe: docs/ci.md, \"Steps\")")?;
        let info = gpu.adapter_info();
        let device = format!("wgpu {} ({:?})", info.name, info.backend);
        (gpu.render(&set, &cam, &settings)?, device)
    };
    let rgb = args.out.join("rgb.png");
    let depth = args.out.join("depth.png");
    let alpha = args.out.join("alpha.png");
    picture::save_rgb_png(&out, &rgb)?;
    picture::save_depth_png(&out, &depth, DepthScale::Auto)?;
    picture::save_alpha_png(&out, &alpha)?;
    println!(
        "rendered {}x{} on {device}: {}, {}, {}",
        out.width,
        out.height,
        rgb.display(),
        depth.display(),
        alpha.display()
    );
    Ok(())
}
