//! Stage 3, key generation (`emit_keys.wgsl`): one (ordered depth, tile) key and Gaussian
//! index per tile each visible Gaussian touches, at its scanned offset, in index order.

use super::context::{self, Cached, Context, WORKGROUP};
use super::FrameBuffers;

/// The key-generation pipeline.
pub(crate) struct EmitKeys {
    kernel: context::Kernel,
    bind_group: Cached<wgpu::BindGroup>,
}

impl EmitKeys {
    /// Compiles the stage.
    pub fn new(ctx: &Context) -> Self {
        Self {
            kernel: ctx.kernel(
                "emit keys",
                wgpu::include_wgsl!("emit_keys.wgsl"),
                &[
                    context::storage(true),
                    context::storage(true),
                    context::storage(true),
                    context::storage(false),
                    context::storage(false),
                    context::uniform(false),
                ],
                16,
            ),
            bind_group: Cached::empty(),
        }
    }

    /// Records key generation for `n` projected Gaussians into `bufs.keys[0]`/`values[0]`
    /// (`bufs.offsets` already scanned), for a grid `grid_x` tiles across.
    pub fn encode(
        &mut self,
        ctx: &Context,
        encoder: &mut wgpu::CommandEncoder,
        bufs: &FrameBuffers,
        n: u32,
        grid_x: u32,
    ) {
        ctx.queue.write_buffer(
            &self.kernel.uniform,
            0,
            bytemuck::cast_slice(&[n, grid_x, 0, 0]),
        );
        let group = self.bind_group.get(ctx, || {
            ctx.bind_group(
                "emit keys",
                &self.kernel.layout,
                &[
                    bufs.splats.get().as_entire_binding(),
                    bufs.rects.get().as_entire_binding(),
                    bufs.offsets.get().as_entire_binding(),
                    bufs.keys[0].get().as_entire_binding(),
                    bufs.values[0].get().as_entire_binding(),
                    self.kernel.uniform.as_entire_binding(),
                ],
            )
        });
        let mut pass = encoder.begin_compute_pass(&Default::default());
        ctx.dispatch(
            &mut pass,
            &self.kernel.pipeline,
            group,
            &[],
            n.div_ceil(WORKGROUP),
        );
    }
}
