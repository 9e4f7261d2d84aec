//! The plumbing every stage shares: the device, buffers that grow, dispatch splitting and
//! read-back.
//!
//! Buffers are created once and only ever grow (capacity doubling), so rendering the same
//! scene again allocates nothing; every allocation bumps one counter, which doubles as the
//! generation stages compare to know when their cached bind groups went stale.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;

use super::GpuError;

/// Invocations per workgroup of every one-dimensional kernel (and of the 16x16 compositor).
pub(crate) const WORKGROUP: u32 = 256;

/// Device, queue and what the adapter told us, plus the allocation counter.
pub(crate) struct Context {
    /// The logical device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Adapter name and backend.
    pub info: wgpu::AdapterInfo,
    /// The limits the device was created with.
    pub limits: wgpu::Limits,
    /// Workgroups per dispatch dimension before a dispatch is split into rows (the device
    /// limit; tests lower it to exercise the split on small inputs).
    pub max_groups: u32,
    allocations: AtomicU64,
}

impl Context {
    /// Picks an adapter (honouring `WGPU_BACKEND`, `WGPU_ADAPTER_NAME`, `WGPU_POWER_PREF`)
    /// and opens a device with the adapter's buffer-size limits, WebGPU defaults otherwise.
    pub fn new() -> Result<Self, GpuError> {
        #[cfg(unix)]
        {
            static RUNTIME_DIR: std::sync::Once = std::sync::Once::new();
            RUNTIME_DIR.call_once(|| {
                super::runtime_dir::ensure_runtime_dir();
            });
        }
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(wgpu::util::initialize_adapter_from_env_or_default(
            &instance, None,
        ))?;
        let available = adapter.limits();
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: available.max_storage_buffer_binding_size,
            max_buffer_size: available.max_buffer_size,
            ..wgpu::Limits::default()
        };
        // Encoder timestamps, when the adapter has them, serve `render_profiled` only.
        let timestamps =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        let (device, queue) =
            pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                label: Some("gaussian rasterizer"),
                required_limits: limits.clone(),
                required_features: adapter.features() & timestamps,
                ..Default::default()
            }))?;
        Ok(Self {
            device,
            queue,
            info: adapter.get_info(),
            max_groups: limits.max_compute_workgroups_per_dimension,
            limits,
            allocations: AtomicU64::new(0),
        })
    }

    /// How many buffers have been created so far (also the bind-group generation).
    pub fn allocations(&self) -> u64 {
        self.allocations.load(Ordering::Relaxed)
    }

    /// The largest storage buffer a stage may bind, bytes.
    pub fn storage_limit(&self) -> u64 {
        self.limits
            .max_buffer_size
            .min(self.limits.max_storage_buffer_binding_size)
    }

    /// Creates a buffer and counts it.
    pub fn buffer(&self, label: &str, size: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
        self.allocations.fetch_add(1, Ordering::Relaxed);
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage,
            mapped_at_creation: false,
        })
    }

    /// A bind-group layout for compute whose bindings are numbered in the order given.
    pub fn layout(&self, label: &str, bindings: &[wgpu::BindingType]) -> wgpu::BindGroupLayout {
        let entries: Vec<_> = bindings
            .iter()
            .enumerate()
            .map(|(i, &ty)| wgpu::BindGroupLayoutEntry {
                binding: i as u32,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty,
                count: None,
            })
            .collect();
        self.device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries: &entries,
            })
    }

    /// A compute pipeline running `entry` of `module` with the single bind group `layout`.
    pub fn pipeline(
        &self,
        label: &str,
        module: &wgpu::ShaderModule,
        layout: &wgpu::BindGroupLayout,
        entry: &str,
    ) -> wgpu::ComputePipeline {
        let pipeline_layout = self
            .device
            .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[Some(layout)],
                immediate_size: 0,
            });
        self.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
    }

    /// A compute kernel with one entry point `main`, its bind-group layout and its settings
    /// uniform: what every single-pipeline stage needs, compiled once.
    pub fn kernel(
        &self,
        label: &str,
        shader: wgpu::ShaderModuleDescriptor<'_>,
        bindings: &[wgpu::BindingType],
        uniform_bytes: u64,
    ) -> Kernel {
        let module = self.device.create_shader_module(shader);
        let layout = self.layout(label, bindings);
        Kernel {
            pipeline: self.pipeline(label, &module, &layout, "main"),
            uniform: self.buffer(
                &format!("{label} settings"),
                uniform_bytes,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            layout,
        }
    }

    /// A bind group whose bindings are numbered in the order given.
    pub fn bind_group(
        &self,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        resources: &[wgpu::BindingResource<'_>],
    ) -> wgpu::BindGroup {
        let entries: Vec<_> = resources
            .iter()
            .enumerate()
            .map(|(i, r)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: r.clone(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &entries,
        })
    }

    /// Records one dispatch of `groups` workgroups, split as [`dispatch_grid`] says.
    pub fn dispatch(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        pipeline: &wgpu::ComputePipeline,
        bind_group: &wgpu::BindGroup,
        offsets: &[u32],
        groups: u32,
    ) {
        let (x, y) = dispatch_grid(groups, self.max_groups);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind_group, offsets);
        pass.dispatch_workgroups(x, y, 1);
    }

    /// Submits `encoder`, waits for it, maps the first `size` bytes of `staging` and hands
    /// them to `read`.
    pub fn submit_and_read<R>(
        &self,
        encoder: wgpu::CommandEncoder,
        staging: &wgpu::Buffer,
        size: u64,
        read: impl FnOnce(&[u8]) -> R,
    ) -> Result<R, GpuError> {
        self.queue.submit([encoder.finish()]);
        self.read(staging, size, read)
    }

    /// Waits for the GPU, maps the first `size` bytes of `staging` (a copy target already
    /// submitted) and hands them to `read`.
    pub fn read<R>(
        &self,
        staging: &wgpu::Buffer,
        size: u64,
        read: impl FnOnce(&[u8]) -> R,
    ) -> Result<R, GpuError> {
        let slice = staging.slice(..size);
        let (tx, rx) = mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            // The receiver lives until after the poll below; a failed send cannot happen.
            let _ = tx.send(r);
        });
        self.device.poll(wgpu::PollType::wait_indefinitely())?;
        rx.recv().map_err(|_| wgpu::BufferAsyncError)??;
        let result = {
            let view = slice.get_mapped_range()?;
            read(&view)
        };
        staging.unmap();
        Ok(result)
    }
}

/// A read-only or writable storage-buffer binding.
/// A compiled single-entry stage (see [`Context::kernel`]).
pub(crate) struct Kernel {
    /// The pipeline running the shader's `main`.
    pub pipeline: wgpu::ComputePipeline,
    /// Its bind-group layout.
    pub layout: wgpu::BindGroupLayout,
    /// Its settings uniform, written before each dispatch.
    pub uniform: wgpu::Buffer,
}

/// A storage-buffer binding.
pub(crate) fn storage(read_only: bool) -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

/// A uniform-buffer binding, with a dynamic offset when one buffer holds several settings.
pub(crate) fn uniform(dynamic: bool) -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: dynamic,
        min_binding_size: None,
    }
}

/// Splits `groups` workgroups into a 2D grid whose dimensions stay within `max_per_dim`;
/// kernels linearise `workgroup_id.x + workgroup_id.y * num_workgroups.x` and skip the
/// excess of the last row.
pub(crate) fn dispatch_grid(groups: u32, max_per_dim: u32) -> (u32, u32) {
    if groups <= max_per_dim {
        (groups, 1)
    } else {
        (max_per_dim, groups.div_ceil(max_per_dim))
    }
}

/// A buffer that keeps its contents' capacity across frames and grows by doubling when a
/// frame needs more (its old contents are not kept).
pub(crate) struct GrowBuffer {
    buffer: wgpu::Buffer,
    capacity: u64,
    usage: wgpu::BufferUsages,
    label: &'static str,
}

impl GrowBuffer {
    /// Smallest capacity, bytes: keeps bindings non-empty for empty frames.
    const MIN_BYTES: u64 = 256;

    /// A buffer of at least `bytes`.
    pub fn new(ctx: &Context, label: &'static str, usage: wgpu::BufferUsages, bytes: u64) -> Self {
        let capacity = bytes.max(Self::MIN_BYTES).next_multiple_of(4);
        Self {
            buffer: ctx.buffer(label, capacity, usage),
            capacity,
            usage,
            label,
        }
    }

    /// Makes room for `bytes`, reallocating (doubling, at most to the device limit) only when
    /// the current capacity is too small; errors when `bytes` exceeds the limit.
    pub fn ensure(&mut self, ctx: &Context, bytes: u64) -> Result<(), GpuError> {
        if bytes <= self.capacity {
            return Ok(());
        }
        let limit = if self.usage.contains(wgpu::BufferUsages::STORAGE) {
            ctx.storage_limit()
        } else {
            ctx.limits.max_buffer_size
        };
        if bytes > limit {
            return Err(GpuError::TooLarge {
                what: self.label,
                bytes,
                limit,
            });
        }
        let capacity = bytes
            .max(self.capacity.saturating_mul(2))
            .min(limit)
            .next_multiple_of(4);
        self.buffer = ctx.buffer(self.label, capacity, self.usage);
        self.capacity = capacity;
        Ok(())
    }

    /// The current buffer (replaced by [`GrowBuffer::ensure`] when it grows).
    pub fn get(&self) -> &wgpu::Buffer {
        &self.buffer
    }
}

/// Bind groups (or anything else built from the buffers) kept until a buffer is reallocated:
/// they are rebuilt when the allocation counter has moved since they were made.
pub(crate) struct Cached<T>(Option<(u64, T)>);

impl<T> Cached<T> {
    /// Nothing cached yet.
    pub fn empty() -> Self {
        Self(None)
    }

    /// The cached value, rebuilt with `make` when any buffer was (re)allocated since.
    pub fn get(&mut self, ctx: &Context, make: impl FnOnce() -> T) -> &T {
        let generation = ctx.allocations();
        if self.0.as_ref().is_some_and(|(g, _)| *g != generation) {
            self.0 = None;
        }
        &self.0.get_or_insert_with(|| (generation, make())).1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dispatches_over_the_dimension_limit_become_two_dimensional() {
        assert_eq!(dispatch_grid(1, 65535), (1, 1));
        assert_eq!(dispatch_grid(65535, 65535), (65535, 1));
        let (x, y) = dispatch_grid(200_000, 65535);
        assert!(x <= 65535 && y <= 65535 && x * y >= 200_000);
        assert_eq!(dispatch_grid(10, 3), (3, 4));
    }
}
