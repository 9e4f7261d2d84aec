//! Stage 6, compositing (`composite.wgsl`): one workgroup per 16x16 tile blends the tile's
//! sorted splats front to back, batch by batch from workgroup memory, and writes every output
//! image of the frame.

use super::context::{self, Cached, Context};
use super::FrameBuffers;
use crate::output::RenderSettings;

/// Output planes per pixel: rgb, depth, raw depth, alpha, confidence, surface depth.
pub(crate) const PLANES: u64 = 8;

/// The `Params` uniform of `composite.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    width: u32,
    height: u32,
    grid_x: u32,
    pixels: u32,
    background: [f32; 4],
    /// x: the transmittance at which the surface depth is taken; y, z, w: padding.
    surface: [f32; 4],
}

/// The compositing pipeline.
pub(crate) struct Composite {
    kernel: context::Kernel,
    bind_groups: Cached<[wgpu::BindGroup; 2]>,
}

impl Composite {
    /// Compiles the stage.
    pub fn new(ctx: &Context) -> Self {
        Self {
            kernel: ctx.kernel(
                "composite",
                wgpu::include_wgsl!("composite.wgsl"),
                &[
                    context::storage(true),
                    context::storage(true),
                    context::storage(true),
                    context::storage(false),
                    context::uniform(false),
                ],
                std::mem::size_of::<Params>() as u64,
            ),
            bind_groups: Cached::empty(),
        }
    }

    /// Records compositing of a `size = [width, height]` image, reading the sorted Gaussian
    /// indices from `bufs.values[sorted]` and the ranges from `bufs.ranges`.
    pub fn encode(
        &mut self,
        ctx: &Context,
        encoder: &mut wgpu::CommandEncoder,
        bufs: &FrameBuffers,
        sorted: usize,
        size: [u32; 2],
        settings: &RenderSettings,
    ) {
        let grid = super::tile_grid(size[0], size[1]);
        let [r, g, b] = settings.background;
        let params = Params {
            width: size[0],
            height: size[1],
            grid_x: grid[0],
            pixels: size[0] * size[1],
            background: [r, g, b, 0.0],
            surface: [1.0 - settings.surface_opacity, 0.0, 0.0, 0.0],
        };
        ctx.queue
            .write_buffer(&self.kernel.uniform, 0, bytemuck::bytes_of(&params));
        let groups = self.bind_groups.get(ctx, || {
            [0, 1].map(|k| {
                ctx.bind_group(
                    "composite",
                    &self.kernel.layout,
                    &[
                        bufs.splats.get().as_entire_binding(),
                        bufs.values[k].get().as_entire_binding(),
                        bufs.ranges.get().as_entire_binding(),
                        bufs.image.get().as_entire_binding(),
                        self.kernel.uniform.as_entire_binding(),
                    ],
                )
            })
        });
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&self.kernel.pipeline);
        pass.set_bind_group(0, &groups[sorted], &[]);
        pass.dispatch_workgroups(grid[0], grid[1], 1);
    }
}
