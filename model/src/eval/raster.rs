//! Which rasterizer draws the evaluation renders: the CPU reference (the default: exact and,
//! without a GPU, the faster one) or wgpu (the node's, fast on a GPU).

use renderer::gpu::{GpuError, GpuRasterizer};
use renderer::{cpu, Camera, GaussianSet, RenderOutput, RenderSettings};

/// A rasterizer for evaluation renders.
pub enum Raster {
    /// [`renderer::cpu::render`] in f32.
    Cpu,
    /// The wgpu rasterizer on whatever adapter it found.
    Gpu(Box<GpuRasterizer>),
}

impl Raster {
    /// A short name for reports.
    pub fn name(&self) -> String {
        match self {
            Raster::Cpu => "cpu".into(),
            Raster::Gpu(gpu) => format!("wgpu {}", gpu.adapter_info().name),
        }
    }

    /// Renders `set` from `cam`.
    pub fn render(
        &mut self,
        set: &GaussianSet,
        cam: &Camera,
        settings: &RenderSettings,
    ) -> Result<RenderOutput, GpuError> {
        match self {
            Raster::Cpu => Ok(cpu::render(&set.view()?, &cam.params::<f32>(), settings).output),
            Raster::Gpu(gpu) => gpu.render(set, cam, settings),
        }
    }
}
