//! What the CPU kernels of [`crate::ops`] share: the scalar types they run in, access to
//! candle's CPU storage, and their error type.

use candle_core::backend::BackendStorage;
use candle_core::{CpuStorage, DType, Layout, WithDType};
use renderer::Real;

/// A scalar the kernels run in: `f32` or `f64`, both candle dtypes and renderer scalars.
pub(crate) trait Float: Real + WithDType {}

impl<T: Real + WithDType> Float for T {}

/// Why an op refused its inputs.
#[derive(Debug, thiserror::Error)]
pub enum OpError {
    /// The op runs on `f32` and `f64` tensors only.
    #[error("{op}: dtype {dtype:?} is not supported (f32 or f64 only)")]
    DType {
        /// The op.
        op: &'static str,
        /// The dtype it was given.
        dtype: DType,
    },
    /// Two inputs' dtypes differ.
    #[error("{op}: inputs have different dtypes ({0:?} and {1:?})", .dtypes.0, .dtypes.1)]
    DTypeMismatch {
        /// The op.
        op: &'static str,
        /// The two dtypes.
        dtypes: (DType, DType),
    },
    /// An input has the wrong shape.
    #[error("{op}: {what}")]
    Shape {
        /// The op.
        op: &'static str,
        /// What is wrong, with the shapes involved.
        what: String,
    },
    /// The kernel was handed a strided view (the public functions make inputs contiguous).
    #[error("{op}: input is not contiguous")]
    NotContiguous {
        /// The op.
        op: &'static str,
    },
    /// A CUDA kernel's source did not compile (NVRTC's log; `cuda` feature only).
    #[error("{op}: the CUDA kernel did not compile: {log}")]
    Compile {
        /// The op.
        op: &'static str,
        /// The compiler's message.
        log: String,
    },
}

impl OpError {
    /// A shape error as a candle error, for `?` in functions returning `candle_core::Result`.
    pub(crate) fn shape(op: &'static str, what: String) -> candle_core::Error {
        candle_core::Error::wrap(OpError::Shape { op, what })
    }
}

/// The contiguous elements of a CPU tensor as a slice of `T`.
pub(crate) fn slice<'a, T: Float>(
    op: &'static str,
    s: &'a CpuStorage,
    l: &Layout,
) -> candle_core::Result<&'a [T]> {
    let (start, end) = l
        .contiguous_offsets()
        .ok_or_else(|| candle_core::Error::wrap(OpError::NotContiguous { op }))?;
    Ok(&s.as_slice::<T>()?[start..end])
}

/// The dtype all of `storages` share, checked to be `f32` or `f64`.
pub(crate) fn float_dtype(
    op: &'static str,
    storages: &[&CpuStorage],
) -> candle_core::Result<DType> {
    let dtype = storages[0].dtype();
    if let Some(other) = storages.iter().map(|s| s.dtype()).find(|&d| d != dtype) {
        return Err(candle_core::Error::wrap(OpError::DTypeMismatch {
            op,
            dtypes: (dtype, other),
        }));
    }
    match dtype {
        DType::F32 | DType::F64 => Ok(dtype),
        dtype => Err(candle_core::Error::wrap(OpError::DType { op, dtype })),
    }
}

/// Runs `$body` with the type alias `$t` set to `f32` or `f64` as `$dtype` says (already
/// checked by [`float_dtype`]) and wraps the `Vec<$t>` it returns as CPU storage: one
/// kernel body serves both dtypes.
macro_rules! float_kernel {
    ($dtype:expr, $t:ident => $body:expr) => {
        match $dtype {
            candle_core::DType::F32 => {
                type $t = f32;
                <f32 as candle_core::WithDType>::to_cpu_storage_owned($body)
            }
            _ => {
                type $t = f64;
                <f64 as candle_core::WithDType>::to_cpu_storage_owned($body)
            }
        }
    };
}
pub(crate) use float_kernel;
