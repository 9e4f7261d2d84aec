//! Stage 4, radix sort (`radix_sort.wgsl`): a stable LSD radix sort of 64-bit (tile, depth)
//! keys with `u32` values, 8 bits a pass. Each pass counts digits per block of 1024 keys,
//! scans the `[digit][block]` counts with the [`PrefixSum`] stage, sorts each block by the
//! digit in workgroup memory and writes it out in runs, each key at its digit's offset plus
//! its rank within the block, which keeps ties in input order.
//!
//! All passes over the low word (the ordered depth bits) run; on the high word (the tile id)
//! only as many as the tile count needs. With keys emitted in Gaussian-index order,
//! stability makes the result exactly the CPU's order: tile, then depth, then index.

use super::context::{self, Cached, Context, GrowBuffer};
use super::prefix_sum::PrefixSum;
use super::GpuError;

/// Bytes of one key (`vec2<u32>`: ordered depth bits, tile id).
pub(crate) const KEY_BYTES: u64 = 8;
/// Bytes of one value (a Gaussian index).
pub(crate) const VALUE_BYTES: u64 = 4;

/// Keys per block (256 invocations, four keys each).
const BLOCK: u32 = 1024;
/// Bits sorted per pass. On an H200 (`results/gpu/`): 8-bit passes sort the
/// 121,856-Gaussian scene's keys in 0.27 ms against 0.43 ms with 4-bit passes of the same
/// design, and 1M-4M Gaussians' in 10-20% less time; 2048-key blocks gained nothing.
const DIGIT_BITS: u32 = 8;
/// Distinct digits.
const RADIX: u32 = 1 << DIGIT_BITS;
/// Passes over both 32-bit words at most.
const MAX_PASSES: usize = (64 / DIGIT_BITS) as usize;
/// Byte stride of the per-pass settings (the uniform dynamic-offset alignment).
const PARAMS_STRIDE: usize = 256;

/// The number of bits a tile id of a grid of `tile_count` tiles can use.
fn tile_bits(tile_count: u32) -> u32 {
    32 - tile_count.saturating_sub(1).leading_zeros()
}

/// The sort's pipelines, settings and digit-count buffers.
pub(crate) struct RadixSort {
    histogram: wgpu::ComputePipeline,
    scatter: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    hist: GrowBuffer,
    scan: PrefixSum,
    groups: Cached<[wgpu::BindGroup; 2]>,
}

impl RadixSort {
    /// Compiles the stage.
    pub fn new(ctx: &Context) -> Self {
        let module = ctx
            .device
            .create_shader_module(wgpu::include_wgsl!("radix_sort.wgsl"));
        let layout = ctx.layout(
            "radix sort",
            &[
                context::storage(true),
                context::storage(true),
                context::storage(false),
                context::storage(false),
                context::storage(false),
                context::uniform(true),
            ],
        );
        Self {
            histogram: ctx.pipeline("radix sort: histogram", &module, &layout, "histogram"),
            scatter: ctx.pipeline("radix sort: scatter", &module, &layout, "scatter"),
            layout,
            params: ctx.buffer(
                "radix sort settings",
                (MAX_PASSES * PARAMS_STRIDE) as u64,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            hist: GrowBuffer::new(ctx, "radix digit counts", wgpu::BufferUsages::STORAGE, 0),
            scan: PrefixSum::new(ctx, "radix digit count sums"),
            groups: Cached::empty(),
        }
    }

    /// Records the sort of the first `n` pairs of `keys[0]`/`values[0]`, whose tile ids are
    /// below `tile_count`. Returns which of the two buffer pairs holds the sorted result.
    pub fn encode(
        &mut self,
        ctx: &Context,
        encoder: &mut wgpu::CommandEncoder,
        keys: &[GrowBuffer; 2],
        values: &[GrowBuffer; 2],
        n: u32,
        tile_count: u32,
    ) -> Result<usize, GpuError> {
        let blocks = n.div_ceil(BLOCK);
        let counts = RADIX * blocks;
        self.hist.ensure(ctx, 4 * counts as u64)?;
        let passes: Vec<(u32, u32)> = (0..32 / DIGIT_BITS)
            .map(|p| (0, p * DIGIT_BITS))
            .chain((0..tile_bits(tile_count).div_ceil(DIGIT_BITS)).map(|p| (1, p * DIGIT_BITS)))
            .collect();
        let mut settings = [0u8; MAX_PASSES * PARAMS_STRIDE];
        for (p, &(word, shift)) in passes.iter().enumerate() {
            let at = p * PARAMS_STRIDE;
            settings[at..at + 16].copy_from_slice(bytemuck::cast_slice(&[n, shift, word, blocks]));
        }
        ctx.queue
            .write_buffer(&self.params, 0, &settings[..passes.len() * PARAMS_STRIDE]);

        let (layout, params, hist) = (&self.layout, &self.params, &self.hist);
        let groups = self.groups.get(ctx, || {
            [(0, 1), (1, 0)].map(|(from, to)| {
                ctx.bind_group(
                    "radix sort",
                    layout,
                    &[
                        keys[from].get().as_entire_binding(),
                        values[from].get().as_entire_binding(),
                        keys[to].get().as_entire_binding(),
                        values[to].get().as_entire_binding(),
                        hist.get().as_entire_binding(),
                        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: params,
                            offset: 0,
                            size: wgpu::BufferSize::new(16),
                        }),
                    ],
                )
            })
        });
        for p in 0..passes.len() {
            let offset = [(p * PARAMS_STRIDE) as u32];
            let group = &groups[p % 2];
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                ctx.dispatch(&mut pass, &self.histogram, group, &offset, blocks);
            }
            self.scan.encode(ctx, encoder, self.hist.get(), counts)?;
            let mut pass = encoder.begin_compute_pass(&Default::default());
            ctx.dispatch(&mut pass, &self.scatter, group, &offset, blocks);
        }
        Ok(passes.len() % 2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_passes_cover_the_largest_tile_id() {
        assert_eq!(tile_bits(1), 0);
        assert_eq!(tile_bits(2), 1);
        assert_eq!(tile_bits(16), 4);
        assert_eq!(tile_bits(17), 5);
        assert_eq!(tile_bits(8160), 13);
    }
}
