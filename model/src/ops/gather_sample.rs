//! [`super::grid_sample`] composed of candle tensor ops (index gathers and bilinear
//! weights), for devices the CPU kernel does not run on: same convention, same zeros
//! outside the image, same zero sample and gradient for NaN and far points; candle's
//! autograd supplies both gradients (the gathers' backward is an index-add).

use candle_core::{DType, Tensor};

use super::cpu::OpError;

/// Coordinates at or beyond this (or NaN) are replaced before any arithmetic, so they
/// sample zero with a zero gradient and no NaN reaches the weights' backward.
const FAR: f64 = 1e9;

/// `grid_sample(input, grid)` from gathers: `input` `(N, C, H, W)`, `grid` `(N, Ho, Wo, 2)`
/// pixel coordinates, giving `(N, C, Ho, Wo)`; any device, `f32` or `f64`. Public so tests
/// compare it with the CPU kernel.
pub fn grid_sample_by_gathers(input: &Tensor, grid: &Tensor) -> candle_core::Result<Tensor> {
    let (n, c, h, w) = input.dims4()?;
    let (gn, ho, wo, two) = grid.dims4()?;
    if gn != n || two != 2 || h == 0 || w == 0 {
        return Err(OpError::shape(
            "grid-sample-by-gathers",
            format!("input {:?} with grid {:?}", input.dims(), grid.dims()),
        ));
    }
    let (dtype, device) = (input.dtype(), input.device());
    let points = ho * wo;
    // Rows of C values, one per input pixel of every image: (N H W, C).
    let rows = input
        .permute((0, 2, 3, 1))?
        .contiguous()?
        .reshape((n * h * w, c))?;
    let coordinate = |axis: usize| -> candle_core::Result<Tensor> {
        let v = grid.narrow(3, axis, 1)?.reshape((n, points))?;
        let near = v.abs()?.lt(FAR)?; // false for NaN and infinities
        near.where_cond(&v, &v.ones_like()?.affine(-2.0, 0.0)?)
    };
    let (x, y) = (coordinate(0)?, coordinate(1)?);
    // A point at or beyond one pixel outside samples zero with a zero gradient (the CPU
    // kernel's rule; the one-sided derivative there would not be zero).
    let reaches = x
        .gt(-1.0)?
        .mul(&x.lt(w as f64)?)?
        .mul(&y.gt(-1.0)?)?
        .mul(&y.lt(h as f64)?)?;
    let (x0, y0) = (x.detach().floor()?, y.detach().floor()?);
    let (fx, fy) = ((&x - &x0)?, (&y - &y0)?);
    let first_row = Tensor::arange(0u32, n as u32, device)?
        .to_dtype(DType::F64)?
        .affine((h * w) as f64, 0.0)?
        .reshape((n, 1))?;
    let zeros = fx.zeros_like()?;
    let mut out: Option<Tensor> = None;
    for (dy, wy) in [(0.0, fy.affine(-1.0, 1.0)?), (1.0, fy.clone())] {
        for (dx, wx) in [(0.0, fx.affine(-1.0, 1.0)?), (1.0, fx.clone())] {
            let xi = x0.affine(1.0, dx)?;
            let yi = y0.affine(1.0, dy)?;
            let inside = xi
                .ge(0.0)?
                .mul(&xi.le((w - 1) as f64)?)?
                .mul(&yi.ge(0.0)?)?
                .mul(&yi.le((h - 1) as f64)?)?
                .mul(&reaches)?;
            let (xi, yi) = (
                inside.where_cond(&xi, &zeros)?,
                inside.where_cond(&yi, &zeros)?,
            );
            let index = yi
                .to_dtype(DType::F64)?
                .affine(w as f64, 0.0)?
                .add(&xi.to_dtype(DType::F64)?)?
                .broadcast_add(&first_row)?
                .to_dtype(DType::U32)?
                .flatten_all()?;
            let weight = inside.where_cond(&(&wx * &wy)?, &zeros)?;
            let tap = rows
                .index_select(&index, 0)?
                .reshape((n, points, c))?
                .broadcast_mul(&weight.unsqueeze(2)?)?;
            out = Some(match out {
                Some(sum) => (sum + tap)?,
                None => tap,
            });
        }
    }
    let out = out.expect("four taps").to_dtype(dtype)?;
    out.permute((0, 2, 1))?
        .contiguous()?
        .reshape((n, c, ho, wo))
}
