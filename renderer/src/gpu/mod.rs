//! The wgpu rasterizer: the forward pass of [`crate::cpu`] as compute shaders, the
//! 3DGS / gsplat way, and the same function (it is tested against the CPU stage by stage).
//!
//! A frame runs six stages, each a WGSL file beside the Rust that launches it:
//! `project` (per Gaussian: splat, tile rectangle, tiles touched), `prefix_sum` (offsets
//! of each Gaussian's keys; the total is read back, one 4-byte map, to size the sort),
//! `emit_keys` ((depth, tile) keys in Gaussian-index order), `radix_sort` (stable LSD
//! radix sort, so ties keep index order as on the CPU), `tile_ranges` (each tile's run in
//! the sorted keys) and `composite` (one workgroup per 16x16 tile).
//!
//! Buffers are created once and reused: they grow (capacity doubling) only when a frame
//! needs more than any frame before, so rendering a scene of a steady size allocates no GPU
//! memory; [`GpuRasterizer::buffer_allocations`] counts allocations so tests can check it.

mod composite;
mod context;
mod emit_keys;
mod prefix_sum;
mod project;
mod radix_sort;
#[cfg(unix)]
pub mod runtime_dir;
mod tile_ranges;
mod timing;

#[cfg(test)]
mod probe;
#[cfg(test)]
mod tests;

use std::time::Instant;

use crate::camera::Camera;
use crate::cpu::TILE_SIZE;
use crate::gaussians::{GaussianSet, LengthMismatch};
use crate::output::{RenderOutput, RenderSettings};
use context::{Context, GrowBuffer};
pub use timing::FrameProfile;
use timing::Timestamps;

/// Why the GPU rasterizer could not be created or could not render.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter matched (no GPU, no software Vulkan/GL driver installed).
    #[error("no GPU adapter found: {0}")]
    NoAdapter(#[from] wgpu::RequestAdapterError),
    /// The adapter refused to open a device with the limits requested.
    #[error("requesting the GPU device failed: {0}")]
    RequestDevice(#[from] wgpu::RequestDeviceError),
    /// Waiting for the GPU failed (device lost, timeout).
    #[error("waiting for the GPU failed: {0}")]
    Poll(#[from] wgpu::PollError),
    /// Mapping a read-back buffer failed.
    #[error("mapping a buffer for read-back failed: {0}")]
    BufferMap(#[from] wgpu::BufferAsyncError),
    /// A mapped read-back range could not be viewed.
    #[error("viewing a mapped buffer failed: {0}")]
    MapRange(#[from] wgpu::MapRangeError),
    /// The frame needs a buffer (or a dispatch) larger than the device allows.
    #[error("input too large: {what} needs {bytes} but the device allows {limit}")]
    TooLarge {
        /// The buffer or quantity that does not fit.
        what: &'static str,
        /// What the frame needs (bytes, or a count for non-buffers).
        bytes: u64,
        /// What the device allows.
        limit: u64,
    },
    /// The Gaussian set's arrays differ in length.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
}

/// Tiles across and down for an image.
pub(crate) fn tile_grid(width: u32, height: u32) -> [u32; 2] {
    [width.div_ceil(TILE_SIZE), height.div_ceil(TILE_SIZE)]
}

/// The buffers one frame flows through, each grown on demand and reused across frames.
pub(crate) struct FrameBuffers {
    /// Input Gaussians, 64 bytes each.
    pub gaussians: GrowBuffer,
    /// Projected splats, 48 bytes each.
    pub splats: GrowBuffer,
    /// Tile rectangles.
    pub rects: GrowBuffer,
    /// Tiles touched per Gaussian, scanned in place into key offsets.
    pub offsets: GrowBuffer,
    /// Sort keys, ping-pong pair.
    pub keys: [GrowBuffer; 2],
    /// Sort values (Gaussian indices), ping-pong pair.
    pub values: [GrowBuffer; 2],
    /// Per-tile (start, end) in the sorted keys.
    pub ranges: GrowBuffer,
    /// The output planes.
    pub image: GrowBuffer,
    /// Mappable copy target for read-back.
    pub readback: GrowBuffer,
}

impl FrameBuffers {
    fn new(ctx: &Context) -> Self {
        use wgpu::BufferUsages as U;
        let storage = U::STORAGE | U::COPY_SRC | U::COPY_DST;
        let grow = |label| GrowBuffer::new(ctx, label, storage, 0);
        Self {
            gaussians: grow("gaussians"),
            splats: grow("splats"),
            rects: grow("tile rectangles"),
            offsets: grow("key offsets"),
            keys: [grow("keys a"), grow("keys b")],
            values: [grow("values a"), grow("values b")],
            ranges: grow("tile ranges"),
            image: grow("image"),
            readback: GrowBuffer::new(ctx, "read-back", U::MAP_READ | U::COPY_DST, 0),
        }
    }
}

/// The wgpu forward rasterizer. Create once and render many frames: pipelines are compiled
/// in [`GpuRasterizer::new`] and buffers are kept between frames.
pub struct GpuRasterizer {
    ctx: Context,
    bufs: FrameBuffers,
    project: project::Project,
    offsets_scan: prefix_sum::PrefixSum,
    emit_keys: emit_keys::EmitKeys,
    sort: radix_sort::RadixSort,
    tile_ranges: tile_ranges::TileRanges,
    composite: composite::Composite,
    packed: Vec<[f32; 16]>,
    /// Stage timestamps of the frame being profiled (`None` outside `render_profiled`, or
    /// where the adapter has none).
    stamps: Option<Timestamps>,
}

impl GpuRasterizer {
    /// Picks an adapter (the `WGPU_BACKEND`, `WGPU_ADAPTER_NAME` and `WGPU_POWER_PREF`
    /// environment variables choose among several), opens a device and compiles the stages.
    pub fn new() -> Result<Self, GpuError> {
        let ctx = Context::new()?;
        Ok(Self {
            bufs: FrameBuffers::new(&ctx),
            project: project::Project::new(&ctx),
            offsets_scan: prefix_sum::PrefixSum::new(&ctx, "key offset sums"),
            emit_keys: emit_keys::EmitKeys::new(&ctx),
            sort: radix_sort::RadixSort::new(&ctx),
            tile_ranges: tile_ranges::TileRanges::new(&ctx),
            composite: composite::Composite::new(&ctx),
            packed: Vec::new(),
            stamps: None,
            ctx,
        })
    }

    /// The adapter's name, backend and driver, for reports and benchmark records.
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.ctx.info
    }

    /// True on a software adapter (Mesa's lavapipe or llvmpipe): the same code runs, but
    /// slower than the CPU reference rasterizer, so callers that only want speed pick that.
    pub fn is_software(&self) -> bool {
        self.ctx.info.device_type == wgpu::DeviceType::Cpu
    }

    /// GPU buffers created since [`GpuRasterizer::new`]: constant over repeated renders of
    /// scenes no larger than one already rendered (buffers are reused, grown only on demand).
    pub fn buffer_allocations(&self) -> u64 {
        self.ctx.allocations()
    }

    /// Renders `set` from `cam`: the same images as [`crate::cpu::render`], computed on the
    /// GPU. Blocks until the images are read back.
    pub fn render(
        &mut self,
        set: &GaussianSet,
        cam: &Camera,
        settings: &RenderSettings,
    ) -> Result<RenderOutput<f32>, GpuError> {
        // The query set stays for the next profiled frame; this frame writes no marks.
        let stamps = self.stamps.take();
        let out = self.render_frame(set, cam, settings, None);
        self.stamps = stamps;
        out
    }

    /// [`Self::render`] with the frame's time split into upload, projection, kernels and
    /// read-back (each phase waited for, so the total is a little above `render`'s) and,
    /// where the adapter writes encoder timestamps, per-stage GPU times.
    pub fn render_profiled(
        &mut self,
        set: &GaussianSet,
        cam: &Camera,
        settings: &RenderSettings,
    ) -> Result<(RenderOutput<f32>, FrameProfile), GpuError> {
        if self.stamps.is_none() {
            self.stamps = Timestamps::new(&self.ctx);
        }
        if let Some(s) = &mut self.stamps {
            s.clear();
        }
        let mut profile = FrameProfile::default();
        let out = self.render_frame(set, cam, settings, Some(&mut profile))?;
        if let Some(s) = &self.stamps {
            profile.stages = s.read(&self.ctx)?;
        }
        Ok((out, profile))
    }

    /// The frame; with `profile`, each phase is waited for and timed.
    fn render_frame(
        &mut self,
        set: &GaussianSet,
        cam: &Camera,
        settings: &RenderSettings,
        mut profile: Option<&mut FrameProfile>,
    ) -> Result<RenderOutput<f32>, GpuError> {
        let (width, height) = (cam.intrinsics.width, cam.intrinsics.height);
        let mut out = RenderOutput::zeros(width, height);
        let pixels = out.pixels();
        if pixels == 0 {
            set.check_lengths()?;
            return Ok(out);
        }
        let intersections = self.project_frame(set, cam, settings, profile.as_deref_mut())?;
        let start = Instant::now();
        let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
        mark(&mut self.stamps, &mut encoder, "count read-back (gap)");
        let sorted = self.encode_binning(&mut encoder, set.len() as u32, intersections, cam)?;
        self.composite.encode(
            &self.ctx,
            &mut encoder,
            &self.bufs,
            sorted,
            [width, height],
            settings,
        );
        mark(&mut self.stamps, &mut encoder, "composite");
        let bytes = composite::PLANES * 4 * pixels as u64;
        if let Some(p) = profile.as_deref_mut() {
            if let Some(s) = &self.stamps {
                s.resolve(&mut encoder);
            }
            self.ctx.queue.submit([encoder.finish()]);
            self.ctx.device.poll(wgpu::PollType::wait_indefinitely())?;
            p.kernels_ms = ms(start);
            encoder = self.ctx.device.create_command_encoder(&Default::default());
        }
        let start = Instant::now();
        encoder.copy_buffer_to_buffer(self.bufs.image.get(), 0, self.bufs.readback.get(), 0, bytes);
        self.ctx
            .submit_and_read(encoder, self.bufs.readback.get(), bytes, |b| {
                let planes: &[f32] = bytemuck::cast_slice(b);
                let (rgb, rest) = planes.split_at(3 * pixels);
                par_copy(&mut out.rgb, rgb);
                for (dst, src) in [
                    &mut out.depth,
                    &mut out.depth_raw,
                    &mut out.alpha,
                    &mut out.confidence,
                    &mut out.surface_depth,
                ]
                .into_iter()
                .zip(rest.chunks_exact(pixels))
                {
                    par_copy(dst, src);
                }
            })?;
        if let Some(p) = profile {
            p.readback_ms = ms(start);
        }
        Ok(out)
    }

    /// Uploads the set, projects it, scans the tiles-touched counts into key offsets and
    /// reads back the number of intersections. Also sizes every buffer whose size the
    /// scene and image determine (so nothing grows between here and the read-back).
    fn project_frame(
        &mut self,
        set: &GaussianSet,
        cam: &Camera,
        settings: &RenderSettings,
        mut profile: Option<&mut FrameProfile>,
    ) -> Result<u32, GpuError> {
        let start = Instant::now();
        set.check_lengths()?;
        let (width, height) = (cam.intrinsics.width, cam.intrinsics.height);
        let grid = tile_grid(width, height);
        let too_large = |what, bytes: u64, limit: u64| GpuError::TooLarge { what, bytes, limit };
        let max_groups = self.ctx.max_groups;
        if grid[0] > max_groups || grid[1] > max_groups {
            return Err(too_large(
                "tiles per image side",
                grid[0].max(grid[1]) as u64,
                max_groups as u64,
            ));
        }
        let n = u32::try_from(set.len())
            .map_err(|_| too_large("Gaussian count", set.len() as u64, u32::MAX as u64))?;
        let n64 = n as u64;
        let pixels = width as u64 * height as u64;
        let image_bytes = composite::PLANES * 4 * pixels;
        let ctx = &self.ctx;
        let b = &mut self.bufs;
        b.gaussians.ensure(ctx, n64 * project::GAUSSIAN_BYTES)?;
        b.splats.ensure(ctx, n64 * project::SPLAT_BYTES)?;
        b.rects.ensure(ctx, n64 * project::RECT_BYTES)?;
        b.offsets.ensure(ctx, n64 * 4)?;
        b.ranges
            .ensure(ctx, (grid[0] * grid[1]) as u64 * tile_ranges::RANGE_BYTES)?;
        b.image.ensure(ctx, image_bytes)?;
        b.readback.ensure(ctx, image_bytes)?;
        if n == 0 {
            return Ok(0);
        }
        project::pack_gaussians(set, &mut self.packed);
        ctx.queue
            .write_buffer(b.gaussians.get(), 0, bytemuck::cast_slice(&self.packed));
        let mut start_projection = start;
        if let Some(p) = profile.as_deref_mut() {
            ctx.queue.submit([]);
            ctx.device.poll(wgpu::PollType::wait_indefinitely())?;
            p.upload_ms = ms(start);
            start_projection = Instant::now();
        }
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        mark(&mut self.stamps, &mut encoder, "start");
        self.project.encode(ctx, &mut encoder, b, cam, settings, n);
        mark(&mut self.stamps, &mut encoder, "project");
        self.offsets_scan
            .encode(ctx, &mut encoder, b.offsets.get(), n)?;
        mark(&mut self.stamps, &mut encoder, "prefix sum");
        if let Some(total) = self.offsets_scan.total() {
            encoder.copy_buffer_to_buffer(total, 0, b.readback.get(), 0, 4);
        }
        let count = self
            .ctx
            .submit_and_read(encoder, self.bufs.readback.get(), 4, |b| {
                bytemuck::pod_read_unaligned::<u32>(&b[..4])
            })?;
        if let Some(p) = profile {
            p.project_ms = ms(start_projection);
        }
        Ok(count)
    }

    /// Records key generation, the sort and the tile ranges for `intersections` keys of `n`
    /// projected Gaussians. Returns which ping-pong buffer holds the sorted keys and values.
    fn encode_binning(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        n: u32,
        intersections: u32,
        cam: &Camera,
    ) -> Result<usize, GpuError> {
        let grid = tile_grid(cam.intrinsics.width, cam.intrinsics.height);
        let ctx = &self.ctx;
        let b = &mut self.bufs;
        encoder.clear_buffer(b.ranges.get(), 0, None);
        if intersections == 0 {
            return Ok(0);
        }
        let m = intersections as u64;
        for k in 0..2 {
            b.keys[k].ensure(ctx, m * radix_sort::KEY_BYTES)?;
            b.values[k].ensure(ctx, m * radix_sort::VALUE_BYTES)?;
        }
        self.emit_keys.encode(ctx, encoder, b, n, grid[0]);
        mark(&mut self.stamps, encoder, "emit keys");
        let sorted = self.sort.encode(
            ctx,
            encoder,
            &b.keys,
            &b.values,
            intersections,
            grid[0] * grid[1],
        )?;
        mark(&mut self.stamps, encoder, "radix sort");
        self.tile_ranges
            .encode(ctx, encoder, b, sorted, intersections);
        mark(&mut self.stamps, encoder, "tile ranges");
        Ok(sorted)
    }
}

/// `dst.copy_from_slice(src)` on every core, in 1 MB pieces: a full-HD frame's planes are
/// 58 MB, which one thread copies out of mapped memory in several milliseconds.
fn par_copy(dst: &mut [f32], src: &[f32]) {
    use rayon::prelude::*;
    const PIECE: usize = 1 << 18;
    dst.par_chunks_mut(PIECE)
        .zip(src.par_chunks(PIECE))
        .for_each(|(d, s)| d.copy_from_slice(s));
}

/// Writes a stage timestamp when a profiled frame is being recorded.
fn mark(stamps: &mut Option<Timestamps>, encoder: &mut wgpu::CommandEncoder, label: &'static str) {
    if let Some(s) = stamps {
        s.mark(encoder, label);
    }
}

/// Milliseconds since `start`.
fn ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}
