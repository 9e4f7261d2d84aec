//! Test hooks: run single stages (or the pipeline up to a stage) on given input and read the
//! intermediate buffers back, so each stage can be compared with the CPU reference.

use super::context::GrowBuffer;
use super::{project, radix_sort, FrameBuffers, GpuError, GpuRasterizer};
use crate::camera::Camera;
use crate::cpu::Projected;
use crate::gaussians::GaussianSet;
use crate::output::RenderSettings;

/// Each Gaussian's projection as the GPU computed it, `None` where culled.
pub(crate) type Projection = Vec<Option<Projected<f32>>>;

impl GpuRasterizer {
    /// Splits dispatches at `max` workgroups per dimension instead of the device limit, so
    /// small inputs exercise the 2D-dispatch path.
    pub(crate) fn set_max_groups_per_dimension(&mut self, max: u32) {
        self.ctx.max_groups = max;
    }

    /// Copies the first `bytes` of `src` back to the host.
    fn read<T: bytemuck::Pod>(
        &mut self,
        src: impl Fn(&Self) -> &wgpu::Buffer,
        bytes: u64,
    ) -> Result<Vec<T>, GpuError> {
        if bytes == 0 {
            return Ok(Vec::new());
        }
        self.bufs.readback.ensure(&self.ctx, bytes)?;
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(src(self), 0, self.bufs.readback.get(), 0, bytes);
        self.ctx.submit_and_read(
            encoder,
            self.bufs.readback.get(),
            bytes,
            bytemuck::pod_collect_to_vec,
        )
    }

    /// Writes `data` to the start of a buffer, growing it first.
    fn upload(
        &mut self,
        which: impl Fn(&mut FrameBuffers) -> &mut GrowBuffer,
        data: &[u8],
    ) -> Result<(), GpuError> {
        let ctx = &self.ctx;
        let buffer = which(&mut self.bufs);
        buffer.ensure(ctx, data.len() as u64)?;
        if !data.is_empty() {
            ctx.queue.write_buffer(buffer.get(), 0, data);
        }
        Ok(())
    }

    /// Runs projection (and the offset scan) and returns each Gaussian's projection, `None`
    /// where culled, plus the intersection count read back for the sort.
    pub(crate) fn probe_project(
        &mut self,
        set: &GaussianSet,
        cam: &Camera,
        settings: &RenderSettings,
    ) -> Result<(Projection, u32), GpuError> {
        let total = self.project_frame(set, cam, settings, None)?;
        let n = set.len() as u64;
        let splats: Vec<[f32; 12]> =
            self.read(|r| r.bufs.splats.get(), n * project::SPLAT_BYTES)?;
        let rects: Vec<[u32; 4]> = self.read(|r| r.bufs.rects.get(), n * project::RECT_BYTES)?;
        let projected = splats
            .iter()
            .zip(&rects)
            .enumerate()
            .map(|(i, (s, r))| {
                (r[0] < r[2] && r[1] < r[3]).then(|| Projected {
                    mean2d: [s[0], s[1]],
                    conic: [s[4], s[5], s[6]],
                    depth: s[3],
                    opacity: s[2],
                    color: set.colors[i].to_array(),
                    confidence: s[7],
                    radius: s[11],
                    tile_min: [r[0], r[1]],
                    tile_max: [r[2], r[3]],
                })
            })
            .collect();
        Ok((projected, total))
    }

    /// Exclusive scan of `values` on the GPU; returns the scanned array and the total.
    pub(crate) fn probe_scan(&mut self, values: &[u32]) -> Result<(Vec<u32>, u32), GpuError> {
        self.upload(|b| &mut b.offsets, bytemuck::cast_slice(values))?;
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        self.offsets_scan.encode(
            &self.ctx,
            &mut encoder,
            self.bufs.offsets.get(),
            values.len() as u32,
        )?;
        self.ctx.queue.submit([encoder.finish()]);
        let scanned = self.read(|r| r.bufs.offsets.get(), 4 * values.len() as u64)?;
        let total = match values.len() {
            0 => 0,
            _ => self.read(|r| r.offsets_scan.total().expect("a scan ran"), 4)?[0],
        };
        Ok((scanned, total))
    }

    /// Sorts (key, value) pairs with the GPU radix sort; keys are `[depth word, tile id]`
    /// with tile ids below `tile_count`.
    pub(crate) fn probe_sort(
        &mut self,
        keys: &[[u32; 2]],
        values: &[u32],
        tile_count: u32,
    ) -> Result<(Vec<[u32; 2]>, Vec<u32>), GpuError> {
        let n = keys.len() as u64;
        self.upload(|b| &mut b.keys[0], bytemuck::cast_slice(keys))?;
        self.upload(|b| &mut b.values[0], bytemuck::cast_slice(values))?;
        self.bufs.keys[1].ensure(&self.ctx, n * radix_sort::KEY_BYTES)?;
        self.bufs.values[1].ensure(&self.ctx, n * radix_sort::VALUE_BYTES)?;
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        let b = &self.bufs;
        let sorted = self.sort.encode(
            &self.ctx,
            &mut encoder,
            &b.keys,
            &b.values,
            n as u32,
            tile_count,
        )?;
        self.ctx.queue.submit([encoder.finish()]);
        let keys = self.read(|r| r.bufs.keys[sorted].get(), n * radix_sort::KEY_BYTES)?;
        let values = self.read(|r| r.bufs.values[sorted].get(), n * radix_sort::VALUE_BYTES)?;
        Ok((keys, values))
    }

    /// Runs projection, key generation, the sort and the tile ranges; returns the GPU
    /// projection and each tile's list of Gaussian indices, front to back.
    pub(crate) fn probe_bins(
        &mut self,
        set: &GaussianSet,
        cam: &Camera,
        settings: &RenderSettings,
    ) -> Result<(Projection, Vec<Vec<u32>>), GpuError> {
        let (projected, total) = self.probe_project(set, cam, settings)?;
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        let sorted = self.encode_binning(&mut encoder, set.len() as u32, total, cam)?;
        self.ctx.queue.submit([encoder.finish()]);
        let grid = super::tile_grid(cam.intrinsics.width, cam.intrinsics.height);
        let tiles = (grid[0] * grid[1]) as u64;
        let ranges: Vec<[u32; 2]> = self.read(|r| r.bufs.ranges.get(), tiles * 8)?;
        let values: Vec<u32> = self.read(|r| r.bufs.values[sorted].get(), total as u64 * 4)?;
        let lists = ranges
            .iter()
            .map(|&[start, end]| values[start as usize..end as usize].to_vec())
            .collect();
        Ok((projected, lists))
    }
}
