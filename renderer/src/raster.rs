//! The one entry point every caller renders through (the node's worker, the evaluation, the
//! progressive pass): which rasterizer draws is the renderer's choice ([`RenderWith`]), made
//! once per thread, so no caller picks between the CPU reference and wgpu by itself.

use crate::gpu::{GpuError, GpuRasterizer};
use crate::{cpu, Camera, GaussianSet, RenderOutput, RenderSettings};

/// How a caller wants its renders drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RenderWith {
    /// The CPU reference rasterizer.
    Cpu,
    /// wgpu; when no adapter is found, say so once and use the CPU instead.
    Gpu,
    /// wgpu on a hardware GPU, else the CPU reference (a software Vulkan adapter runs the
    /// same shaders several times slower than the CPU reference).
    #[default]
    Auto,
}

impl RenderWith {
    /// The rasterizer, made on the thread that will use it (wgpu devices are per thread).
    pub fn raster(self) -> Raster {
        match self {
            RenderWith::Cpu => Raster::Cpu,
            RenderWith::Gpu => match GpuRasterizer::new() {
                Ok(gpu) => Raster::Gpu(Box::new(gpu)),
                Err(e) => {
                    eprintln!("renderer: no wgpu adapter ({e}); rendering on the CPU");
                    Raster::Cpu
                }
            },
            RenderWith::Auto => match GpuRasterizer::new() {
                Ok(gpu) if !gpu.is_software() => Raster::Gpu(Box::new(gpu)),
                _ => Raster::Cpu,
            },
        }
    }
}

/// A rasterizer: the CPU reference (exact and, without a GPU, the faster one) or wgpu.
pub enum Raster {
    /// [`cpu::render`] in f32.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cpu_choice_renders_and_names_itself() {
        let mut raster = RenderWith::Cpu.raster();
        assert_eq!(raster.name(), "cpu");
        let cam = Camera::identity(crate::Intrinsics::from_hfov(8, 6, 90.0));
        let out = raster
            .render(&GaussianSet::default(), &cam, &RenderSettings::default())
            .unwrap();
        assert_eq!((out.width, out.height), (8, 6));
    }
}
