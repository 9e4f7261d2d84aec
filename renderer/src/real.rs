//! The scalar the CPU rasterizer is generic over.
//!
//! The rasterizer runs in `f32` for speed and in `f64` for gradient checks against finite
//! differences, so its arithmetic is written once over this trait.

use std::cmp::Ordering;
use std::fmt::Debug;

/// A floating-point scalar (`f32` or `f64`) the CPU rasterizer can run in.
pub trait Real: num_traits::Float + Debug + Default + Send + Sync + 'static {
    /// Converts an `f64` constant into this scalar (rounding for `f32`).
    fn c(v: f64) -> Self;
    /// Converts to `f64`, for reporting and comparisons in tests.
    fn f64(self) -> f64;
    /// IEEE total order; on finite positive values it agrees with the GPU's ordering of the
    /// raw bits, which keeps CPU and GPU depth sorts identical.
    fn total_cmp(&self, other: &Self) -> Ordering;
}

impl Real for f32 {
    fn c(v: f64) -> Self {
        v as f32
    }
    fn f64(self) -> f64 {
        self as f64
    }
    fn total_cmp(&self, other: &Self) -> Ordering {
        f32::total_cmp(self, other)
    }
}

impl Real for f64 {
    fn c(v: f64) -> Self {
        v
    }
    fn f64(self) -> f64 {
        self
    }
    fn total_cmp(&self, other: &Self) -> Ordering {
        f64::total_cmp(self, other)
    }
}
