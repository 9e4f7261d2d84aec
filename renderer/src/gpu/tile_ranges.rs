//! Stage 5, tile ranges (`tile_ranges.wgsl`): where each tile's run starts and ends in the
//! sorted keys; tiles without Gaussians are left at the cleared (0, 0).

use super::context::{self, Cached, Context, WORKGROUP};
use super::FrameBuffers;

/// Bytes of one tile's range (`vec2<u32>`).
pub(crate) const RANGE_BYTES: u64 = 8;

/// The tile-range pipeline.
pub(crate) struct TileRanges {
    kernel: context::Kernel,
    bind_groups: Cached<[wgpu::BindGroup; 2]>,
}

impl TileRanges {
    /// Compiles the stage.
    pub fn new(ctx: &Context) -> Self {
        Self {
            kernel: ctx.kernel(
                "tile ranges",
                wgpu::include_wgsl!("tile_ranges.wgsl"),
                &[
                    context::storage(true),
                    context::storage(false),
                    context::uniform(false),
                ],
                16,
            ),
            bind_groups: Cached::empty(),
        }
    }

    /// Records the ranges of the `n` sorted keys in `bufs.keys[sorted]` into `bufs.ranges`
    /// (which the caller cleared).
    pub fn encode(
        &mut self,
        ctx: &Context,
        encoder: &mut wgpu::CommandEncoder,
        bufs: &FrameBuffers,
        sorted: usize,
        n: u32,
    ) {
        ctx.queue
            .write_buffer(&self.kernel.uniform, 0, bytemuck::cast_slice(&[n, 0, 0, 0]));
        let groups = self.bind_groups.get(ctx, || {
            [0, 1].map(|k| {
                ctx.bind_group(
                    "tile ranges",
                    &self.kernel.layout,
                    &[
                        bufs.keys[k].get().as_entire_binding(),
                        bufs.ranges.get().as_entire_binding(),
                        self.kernel.uniform.as_entire_binding(),
                    ],
                )
            })
        });
        let mut pass = encoder.begin_compute_pass(&Default::default());
        ctx.dispatch(
            &mut pass,
            &self.kernel.pipeline,
            &groups[sorted],
            &[],
            n.div_ceil(WORKGROUP),
        );
    }
}
