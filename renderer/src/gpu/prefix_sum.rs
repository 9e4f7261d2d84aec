//! Stage 2, prefix sum (`prefix_sum.wgsl`): an in-place exclusive scan of a `u32` array of
//! any length, the classic multi-level way: scan blocks of 1024 and collect their totals,
//! scan those totals the same way (recursively, until one block remains), then add each
//! block's offset back. The last level's single total is the sum of the whole array.
//!
//! Used for the tiles-touched counts (their scan gives each Gaussian's key offset and the
//! number of intersections) and by the radix sort for its digit histograms.

use super::context::{self, Cached, Context, GrowBuffer};
use super::GpuError;

/// Values one workgroup scans.
const BLOCK: u32 = 1024;

/// One level of the scan: its block totals and its element count.
struct Level {
    sums: GrowBuffer,
    params: wgpu::Buffer,
}

/// A reusable multi-level scan; its level buffers grow with the largest input seen.
pub(crate) struct PrefixSum {
    scan: wgpu::ComputePipeline,
    add: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    levels: Vec<Level>,
    groups: Cached<Vec<wgpu::BindGroup>>,
    /// The data buffer the cached bind groups were built for.
    bound: Option<wgpu::Buffer>,
    /// Levels the last scan used.
    used: usize,
    label: &'static str,
}

impl PrefixSum {
    /// Compiles the stage; `label` names its buffers.
    pub fn new(ctx: &Context, label: &'static str) -> Self {
        let module = ctx
            .device
            .create_shader_module(wgpu::include_wgsl!("prefix_sum.wgsl"));
        let layout = ctx.layout(
            "prefix sum",
            &[
                context::storage(false),
                context::storage(false),
                context::uniform(false),
            ],
        );
        Self {
            scan: ctx.pipeline("prefix sum: scan blocks", &module, &layout, "scan_blocks"),
            add: ctx.pipeline(
                "prefix sum: add block offsets",
                &module,
                &layout,
                "add_sums",
            ),
            layout,
            levels: Vec::new(),
            groups: Cached::empty(),
            bound: None,
            used: 0,
            label,
        }
    }

    /// Element counts per level for `n` values: `n`, then the block totals of each level
    /// until a level fits one block.
    fn sizes(n: u32) -> Vec<u32> {
        let mut sizes = vec![n];
        while let Some(&last) = sizes.last().filter(|&&s| s > BLOCK) {
            sizes.push(last.div_ceil(BLOCK));
        }
        sizes
    }

    /// Records the exclusive scan of the first `n` values of `data` (nothing when `n` is 0).
    /// Afterwards the first `u32` of [`PrefixSum::total`] holds their sum, saturated at
    /// `u32::MAX`.
    pub fn encode(
        &mut self,
        ctx: &Context,
        encoder: &mut wgpu::CommandEncoder,
        data: &wgpu::Buffer,
        n: u32,
    ) -> Result<(), GpuError> {
        if n == 0 {
            return Ok(());
        }
        let sizes = Self::sizes(n);
        for (k, &size) in sizes.iter().enumerate() {
            let bytes = 4 * size.div_ceil(BLOCK) as u64;
            match self.levels.get_mut(k) {
                Some(level) => level.sums.ensure(ctx, bytes)?,
                None => self.levels.push(Level {
                    sums: GrowBuffer::new(
                        ctx,
                        self.label,
                        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                        bytes,
                    ),
                    params: ctx.buffer(
                        self.label,
                        16,
                        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    ),
                }),
            }
            ctx.queue.write_buffer(
                &self.levels[k].params,
                0,
                bytemuck::cast_slice(&[size, 0, 0, 0]),
            );
        }
        if self.bound.as_ref() != Some(data) {
            self.groups = Cached::empty();
            self.bound = Some(data.clone());
        }
        self.used = sizes.len();
        let (levels, layout) = (&self.levels, &self.layout);
        let groups = self.groups.get(ctx, || {
            (0..levels.len())
                .map(|k| {
                    let input = if k == 0 {
                        data
                    } else {
                        levels[k - 1].sums.get()
                    };
                    ctx.bind_group(
                        "prefix sum",
                        layout,
                        &[
                            input.as_entire_binding(),
                            levels[k].sums.get().as_entire_binding(),
                            levels[k].params.as_entire_binding(),
                        ],
                    )
                })
                .collect()
        });
        let mut pass = encoder.begin_compute_pass(&Default::default());
        for (k, &size) in sizes.iter().enumerate() {
            ctx.dispatch(&mut pass, &self.scan, &groups[k], &[], size.div_ceil(BLOCK));
        }
        for (k, &size) in sizes.iter().enumerate().rev().skip(1) {
            ctx.dispatch(&mut pass, &self.add, &groups[k], &[], size.div_ceil(BLOCK));
        }
        Ok(())
    }

    /// The buffer whose first `u32` is the total of the last [`PrefixSum::encode`] with
    /// `n > 0` (`None` before any).
    pub fn total(&self) -> Option<&wgpu::Buffer> {
        Some(self.levels.get(self.used.checked_sub(1)?)?.sums.get())
    }
}
