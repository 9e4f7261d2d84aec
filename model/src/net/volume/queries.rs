//! The triplane's learned queries (TPVFormer's): one embedding per cell of each plane, and a
//! learned positional code per plane made of a row code and a column code (the per-axis
//! code cross-plane attention adds to its queries). Also [`Planes`], the triplane features
//! every block of the branch passes around, and the token layout the attention blocks use.

use candle_core::{Result, Tensor};
use candle_nn::{Init, VarBuilder};

use super::{Plane, VolumeConfig};

/// The three plane features in the order [`Plane::ALL`], each `(C, rows, columns)` with the
/// shapes [`VolumeConfig::plane_shapes`] gives: XZ `(C, cells_z, cells_x)`, XY `(C, cells_y,
/// cells_x)`, ZY `(C, cells_y, cells_z)`.
#[derive(Clone, Debug)]
pub struct Planes(pub [Tensor; 3]);

impl Planes {
    /// The plane `plane`'s tensor.
    pub fn get(&self, plane: Plane) -> &Tensor {
        &self.0[super::anchors::plane_index(plane)]
    }

    /// The planes as tokens `(rows * columns, C)`, cells row-major: the layout the attention
    /// blocks work in.
    pub fn to_tokens(&self) -> Result<[Tensor; 3]> {
        let t = |p: &Tensor| -> Result<Tensor> {
            let (c, r, k) = p.dims3()?;
            p.reshape((c, r * k))?.t()?.contiguous()
        };
        Ok([t(&self.0[0])?, t(&self.0[1])?, t(&self.0[2])?])
    }

    /// Planes of `cfg`'s shapes from tokens `(rows * columns, C)` (the inverse of
    /// [`Planes::to_tokens`]).
    pub fn from_tokens(cfg: &VolumeConfig, tokens: &[Tensor; 3]) -> Result<Self> {
        let shapes = cfg.plane_shapes();
        let p = |i: usize| -> Result<Tensor> {
            let (rows, cols) = shapes[i];
            let c = tokens[i].dim(1)?;
            tokens[i].t()?.reshape((c, rows, cols))?.contiguous()
        };
        Ok(Self([p(0)?, p(1)?, p(2)?]))
    }
}

/// The learned queries and positional codes of the three planes.
#[derive(Clone, Debug)]
pub struct PlaneQueries {
    /// Per plane, `(rows * columns, C)`.
    embeddings: [Tensor; 3],
    /// Per plane, the row code `(rows, C / 2)` and the column code `(columns, C - C / 2)`.
    codes: [(Tensor, Tensor); 3],
}

impl PlaneQueries {
    /// Embeddings `N(0, 1)` (as a PyTorch `Embedding`), positional codes uniform in [0, 1]
    /// (as TPVFormer's learned positional encoding), under `vb` (`xz`, `xy`, `zy`).
    pub fn new(vb: VarBuilder, cfg: &VolumeConfig) -> Result<Self> {
        let c = cfg.channels;
        let shapes = cfg.plane_shapes();
        let names = ["xz", "xy", "zy"];
        let one = |i: usize| -> Result<(Tensor, (Tensor, Tensor))> {
            let vb = vb.pp(names[i]);
            let (rows, cols) = shapes[i];
            let normal = Init::Randn {
                mean: 0.0,
                stdev: 1.0,
            };
            let uniform = Init::Uniform { lo: 0.0, up: 1.0 };
            Ok((
                vb.get_with_hints((rows * cols, c), "embedding", normal)?,
                (
                    vb.get_with_hints((rows, c / 2), "row_code", uniform)?,
                    vb.get_with_hints((cols, c - c / 2), "column_code", uniform)?,
                ),
            ))
        };
        let (e0, p0) = one(0)?;
        let (e1, p1) = one(1)?;
        let (e2, p2) = one(2)?;
        Ok(Self {
            embeddings: [e0, e1, e2],
            codes: [p0, p1, p2],
        })
    }

    /// The initial queries as tokens `(rows * columns, C)` per plane.
    pub fn forward(&self) -> [Tensor; 3] {
        self.embeddings.clone()
    }

    /// The positional code of each plane's cells as tokens `(rows * columns, C)`: the row's
    /// code joined with the column's.
    pub fn positions(&self) -> Result<[Tensor; 3]> {
        let one = |(row, col): &(Tensor, Tensor)| -> Result<Tensor> {
            let (r, a) = row.dims2()?;
            let (k, b) = col.dims2()?;
            let row = row.unsqueeze(1)?.broadcast_as((r, k, a))?;
            let col = col.unsqueeze(0)?.broadcast_as((r, k, b))?;
            Tensor::cat(&[row, col], 2)?.reshape((r * k, a + b))
        };
        Ok([
            one(&self.codes[0])?,
            one(&self.codes[1])?,
            one(&self.codes[2])?,
        ])
    }
}
