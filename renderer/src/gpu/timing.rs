//! Where a frame's time goes on the GPU, for `GpuRasterizer::render_profiled`: wall-clock
//! phases, each closed by waiting for the GPU (upload, projection with the read-back of
//! the key count, the kernels after it, the image read-back), and per-stage GPU timestamps
//! where the adapter can write them between compute passes
//! (`TIMESTAMP_QUERY_INSIDE_ENCODERS`: Vulkan and DX12, not WebGPU). `render` itself
//! neither waits between phases nor writes timestamps.

use super::context::Context;
use super::GpuError;

/// Timestamps one frame can write (two per stage would still fit).
const SLOTS: u32 = 16;

/// One profiled frame, milliseconds.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameProfile {
    /// Packing the Gaussians and copying them to the GPU.
    pub upload_ms: f64,
    /// Projection and the prefix sum, with the 4-byte read-back of the key count that sizes
    /// the sort (a CPU-GPU round trip).
    pub project_ms: f64,
    /// Key emission, sort, tile ranges and compositing.
    pub kernels_ms: f64,
    /// Copying the output planes to a mappable buffer and into the output images.
    pub readback_ms: f64,
    /// GPU time of each stage from timestamps (empty where the adapter has none): the time
    /// from the previous mark to this one, in order; the gap between the two submissions
    /// (the count read-back) is named as such.
    pub stages: Vec<(&'static str, f64)>,
}

/// A query set written at stage boundaries, resolved at the end of the frame.
pub(crate) struct Timestamps {
    set: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    staging: wgpu::Buffer,
    labels: Vec<&'static str>,
    period_ns: f64,
}

impl Timestamps {
    /// The query set, when the device was opened with encoder timestamps.
    pub fn new(ctx: &Context) -> Option<Self> {
        let needed =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        if !ctx.device.features().contains(needed) {
            return None;
        }
        let bytes = SLOTS as u64 * 8;
        Some(Self {
            set: ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("stage timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: SLOTS,
            }),
            resolved: ctx.buffer(
                "resolved timestamps",
                bytes,
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            ),
            staging: ctx.buffer(
                "timestamp read-back",
                bytes,
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            labels: Vec::new(),
            period_ns: ctx.queue.get_timestamp_period() as f64,
        })
    }

    /// Forgets the last frame's marks.
    pub fn clear(&mut self) {
        self.labels.clear();
    }

    /// Writes a timestamp closing the stage `label` (the first mark of a frame opens it).
    pub fn mark(&mut self, encoder: &mut wgpu::CommandEncoder, label: &'static str) {
        let index = self.labels.len() as u32;
        if index < SLOTS {
            encoder.write_timestamp(&self.set, index);
            self.labels.push(label);
        }
    }

    /// Records the copy of every mark so far to the mappable buffer.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        let n = self.labels.len() as u32;
        if n > 0 {
            encoder.resolve_query_set(&self.set, 0..n, &self.resolved, 0);
            encoder.copy_buffer_to_buffer(&self.resolved, 0, &self.staging, 0, n as u64 * 8);
        }
    }

    /// The stage times of the resolved marks (call after the resolving submission ran).
    pub fn read(&self, ctx: &Context) -> Result<Vec<(&'static str, f64)>, GpuError> {
        let n = self.labels.len();
        if n < 2 {
            return Ok(Vec::new());
        }
        let ticks: Vec<u64> = ctx.read(&self.staging, n as u64 * 8, |b| {
            bytemuck::cast_slice(b).to_vec()
        })?;
        Ok(self.labels[1..]
            .iter()
            .zip(ticks.windows(2))
            .map(|(&label, t)| {
                (
                    label,
                    t[1].saturating_sub(t[0]) as f64 * self.period_ns / 1e6,
                )
            })
            .collect())
    }
}
