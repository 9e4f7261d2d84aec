//! Stage 1, projection (`project.wgsl`): each Gaussian to its screen-space splat, tile
//! rectangle and tiles-touched count, with the CPU reference's culling rules and arithmetic.

use rayon::prelude::*;

use super::context::{self, Cached, Context, WORKGROUP};
use super::FrameBuffers;
use crate::camera::Camera;
use crate::gaussians::GaussianSet;
use crate::output::RenderSettings;

/// Bytes of one input Gaussian on the GPU (four `vec4<f32>`).
pub(crate) const GAUSSIAN_BYTES: u64 = 64;
/// Bytes of one projected splat (three `vec4<f32>`).
pub(crate) const SPLAT_BYTES: u64 = 48;
/// Bytes of one tile rectangle (`vec4<u32>`).
pub(crate) const RECT_BYTES: u64 = 16;

/// The `Camera` uniform of `project.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct CameraUniform {
    rows: [[f32; 4]; 3],
    position: [f32; 4],
    intrinsics: [f32; 4],
    limits: [f32; 4],
    clip: [f32; 4],
    grid: [u32; 4],
}

impl CameraUniform {
    /// The frustum-clamp limits are computed here with the very expressions of
    /// `cpu::project` in `f32`, so both rasterizers clamp at bit-identical bounds.
    fn new(cam: &Camera, settings: &RenderSettings, grid: [u32; 2], n: u32) -> Self {
        let p = cam.params::<f32>();
        let w = p.width as f32;
        let h = p.height as f32;
        let margin = (0.3 * 0.5) as f32;
        let limits = [
            (w - p.cx) / p.fx + margin * w / p.fx,
            p.cx / p.fx + margin * w / p.fx,
            (h - p.cy) / p.fy + margin * h / p.fy,
            p.cy / p.fy + margin * h / p.fy,
        ];
        let row = |r: [f32; 3]| [r[0], r[1], r[2], 0.0];
        Self {
            rows: p.rotation.map(row),
            position: row(p.position),
            intrinsics: [p.fx, p.fy, p.cx, p.cy],
            limits,
            clip: [settings.near, settings.far, 0.0, 0.0],
            grid: [grid[0], grid[1], n, 0],
        }
    }
}

/// Interleaves a set into the 64-byte records `project.wgsl` reads, reusing `out`, on
/// every core (one thread took 20 ms of a 1M-Gaussian frame's upload on an H200's host).
pub(crate) fn pack_gaussians(set: &GaussianSet, out: &mut Vec<[f32; 16]>) {
    let records = (0..set.len()).into_par_iter().map(|i| {
        let (m, s, q, c) = (
            set.means[i],
            set.log_scales[i],
            set.rotations[i],
            set.colors[i],
        );
        [
            m.x,
            m.y,
            m.z,
            set.opacities[i],
            s.x,
            s.y,
            s.z,
            set.confidences[i],
            q.x,
            q.y,
            q.z,
            q.w,
            c.x,
            c.y,
            c.z,
            0.0,
        ]
    });
    records.collect_into_vec(out);
}

/// The projection pipeline and its camera uniform.
pub(crate) struct Project {
    kernel: context::Kernel,
    bind_group: Cached<wgpu::BindGroup>,
}

impl Project {
    /// Compiles the stage.
    pub fn new(ctx: &Context) -> Self {
        Self {
            kernel: ctx.kernel(
                "project",
                wgpu::include_wgsl!("project.wgsl"),
                &[
                    context::storage(true),
                    context::uniform(false),
                    context::storage(false),
                    context::storage(false),
                    context::storage(false),
                ],
                std::mem::size_of::<CameraUniform>() as u64,
            ),
            bind_group: Cached::empty(),
        }
    }

    /// Records projection of the `n` Gaussians already uploaded to `bufs.gaussians`.
    pub fn encode(
        &mut self,
        ctx: &Context,
        encoder: &mut wgpu::CommandEncoder,
        bufs: &FrameBuffers,
        cam: &Camera,
        settings: &RenderSettings,
        n: u32,
    ) {
        let grid = super::tile_grid(cam.intrinsics.width, cam.intrinsics.height);
        let uniform = CameraUniform::new(cam, settings, grid, n);
        ctx.queue
            .write_buffer(&self.kernel.uniform, 0, bytemuck::bytes_of(&uniform));
        let group = self.bind_group.get(ctx, || {
            ctx.bind_group(
                "project",
                &self.kernel.layout,
                &[
                    bufs.gaussians.get().as_entire_binding(),
                    self.kernel.uniform.as_entire_binding(),
                    bufs.splats.get().as_entire_binding(),
                    bufs.rects.get().as_entire_binding(),
                    bufs.offsets.get().as_entire_binding(),
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
