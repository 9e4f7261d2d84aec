//! The bilinear sampler's kernels on CUDA (`bilinear.cu`, `cuda` feature): forward, input
//! gradient and grid gradient as one launch each, where the gather formulation
//! ([`super::grid_sample_by_gathers`]) launches about 95 small kernels per call. The source
//! is compiled once per process by NVRTC (which candle's CUDA backend already links), so
//! the build needs no extra step.

use std::sync::OnceLock;

use candle_core::backend::BackendStorage;
use candle_core::cuda_backend::cudarc::driver::{
    CudaSlice, DeviceRepr, LaunchConfig, PushKernelArg, ValidAsZeroBits,
};
use candle_core::cuda_backend::cudarc::nvrtc::{compile_ptx_with_opts, CompileOptions};
use candle_core::cuda_backend::{CudaDType, WrapErr};
use candle_core::{CudaStorage, DType, Layout, Result, WithDType};

use super::cpu::OpError;

/// The kernels' CUDA C source.
const SOURCE: &str = include_str!("bilinear.cu");
/// The name the loaded module is cached under on each device.
const MODULE: &str = "stereosplat_bilinear";
/// Threads per block of every launch.
const THREADS_PER_BLOCK: u32 = 256;

/// The PTX of [`SOURCE`], compiled on first use. PTX for compute capability 7.5 (CUDA 13's
/// oldest), which the driver compiles for the GPU at hand; no fused multiply-add, so the
/// sums round as the CPU kernels' do.
fn ptx(op: &'static str) -> Result<&'static str> {
    static PTX: OnceLock<std::result::Result<String, String>> = OnceLock::new();
    PTX.get_or_init(|| {
        let opts = CompileOptions {
            arch: Some("compute_75"),
            fmad: Some(false),
            ..Default::default()
        };
        compile_ptx_with_opts(SOURCE, opts)
            .map(|p| p.to_src())
            .map_err(|e| format!("{e:?}"))
    })
    .as_deref()
    .map_err(|log| {
        candle_core::Error::wrap(OpError::Compile {
            op,
            log: log.to_string(),
        })
    })
}

/// One launch of a kernel of `bilinear.cu`.
pub(super) struct Kernel {
    /// The op, for errors.
    pub op: &'static str,
    /// The kernel's name without its dtype suffix.
    pub name: &'static str,
    /// The sizes every kernel takes, in its argument order: channels `c`, the input plane's
    /// `h` and `w`, output points per plane `p`.
    pub sizes: [usize; 4],
    /// How many threads it runs (one per output value or point).
    pub threads: usize,
    /// Values in its output buffer.
    pub out_len: usize,
    /// Whether the output starts at zero (kernels that accumulate).
    pub zeroed: bool,
}

impl Kernel {
    /// Runs the kernel on `inputs` (contiguous storages of one float dtype) into a new
    /// buffer.
    pub fn launch(&self, inputs: &[(&CudaStorage, &Layout)]) -> Result<CudaStorage> {
        let op = self.op;
        let dtype = inputs[0].0.dtype();
        if let Some(other) = inputs.iter().map(|(s, _)| s.dtype()).find(|&d| d != dtype) {
            return Err(candle_core::Error::wrap(OpError::DTypeMismatch {
                op,
                dtypes: (dtype, other),
            }));
        }
        match dtype {
            DType::F32 => self.typed::<f32>(inputs),
            DType::F64 => self.typed::<f64>(inputs),
            dtype => Err(candle_core::Error::wrap(OpError::DType { op, dtype })),
        }
    }

    /// [`Self::launch`] for element type `T`.
    fn typed<T>(&self, inputs: &[(&CudaStorage, &Layout)]) -> Result<CudaStorage>
    where
        T: CudaDType + WithDType + DeviceRepr + ValidAsZeroBits,
    {
        let (op, device) = (self.op, inputs[0].0.device.clone());
        let out: CudaSlice<T> = if self.zeroed {
            device.alloc_zeros::<T>(self.out_len)?
        } else {
            // SAFETY: every element is written by the kernel (one thread per element).
            unsafe { device.alloc::<T>(self.out_len)? }
        };
        if self.threads == 0 {
            return Ok(CudaStorage::wrap_cuda_slice(out, device));
        }
        let views = inputs
            .iter()
            .map(|(s, l)| {
                let (start, end) = l
                    .contiguous_offsets()
                    .ok_or_else(|| candle_core::Error::wrap(OpError::NotContiguous { op }))?;
                Ok(s.as_cuda_slice::<T>()?.slice(start..end))
            })
            .collect::<Result<Vec<_>>>()?;
        let func = device.get_or_load_custom_func(
            &format!("{}_{}", self.name, T::DTYPE.as_str()),
            MODULE,
            ptx(op)?,
        )?;
        let int = |v: usize| i32::try_from(v).map_err(|_| too_large(op, v));
        let sizes: Vec<i32> = self.sizes.map(int).into_iter().collect::<Result<_>>()?;
        let [_, h, w, _] = self.sizes;
        int(h * w)?; // the kernels' flat pixel index within a plane
        let total = self.threads as i64;
        let blocks = self.threads.div_ceil(THREADS_PER_BLOCK as usize);
        let blocks = u32::try_from(blocks).map_err(|_| too_large(op, self.threads))?;
        let mut builder = func.builder();
        for view in &views {
            builder.arg(view);
        }
        builder.arg(&out);
        for v in &sizes {
            builder.arg(v);
        }
        builder.arg(&total);
        let config = LaunchConfig {
            grid_dim: (blocks, 1, 1),
            block_dim: (THREADS_PER_BLOCK, 1, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: the argument list matches the kernel's signature in bilinear.cu, and every
        // index the kernel forms stays inside the buffers for these sizes.
        unsafe { builder.launch(config) }.w()?;
        Ok(CudaStorage::wrap_cuda_slice(out, device))
    }
}

/// A size the kernels' 32-bit indices cannot hold.
fn too_large(op: &'static str, v: usize) -> candle_core::Error {
    OpError::shape(
        op,
        format!("size {v} is beyond the CUDA kernel's 32-bit indices"),
    )
}

#[cfg(test)]
mod tests {
    /// The source compiles (NVRTC runs without a GPU; the kernels themselves are checked
    /// against the CPU on a GPU machine by `tests/cuda_ops.rs`).
    #[test]
    fn the_kernels_compile() {
        let ptx = super::ptx("test").unwrap();
        for name in [
            "grid_sample",
            "grid_sample_input_grad",
            "grid_sample_grid_grad",
        ] {
            for suffix in ["f32", "f64"] {
                assert!(
                    ptx.contains(&format!(".entry {name}_{suffix}(")),
                    "{name}_{suffix}"
                );
            }
        }
    }
}
