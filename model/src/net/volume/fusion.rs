//! Projection-guided fusion (paper section 3.2.2): the cost-volume branch's Gaussians carry
//! their features into the triplane. Each Gaussian whose centre lies in the volume lands in
//! one cell of every plane; a cell's feature is the mean over the Gaussians that land in it,
//! adapted by a linear layer (k -> C) and returned as an additive prior for the plane
//! queries. Cells no Gaussian reaches get zero (no prior). Centres outside the volume or not
//! finite are dropped.
//!
//! The centres only decide where a feature goes (they are read on the CPU, no gradient); the
//! features and the adapter get exact gradients: the pooling is an `index_select` and an
//! `index_add` (candle's `scatter_add` gradient for its `init` is not trusted, see
//! `../shared/METHOD_NOTES.md`), checked against finite differences in
//! `model/tests/integration/volume_fusion.rs`.

use candle_core::{DType, Module, Result, Tensor};
use candle_nn::{linear, Linear, VarBuilder};

use super::voxels::{index_tensor, plane_cell};
use super::{Plane, VolumeConfig};
use crate::ops::transpose_last2;

/// The fusion block: pooling into the planes' cells and the adapter.
#[derive(Clone, Debug)]
pub struct ProjectionFusion {
    adapter: Linear,
    features: usize,
    cfg: VolumeConfig,
}

/// Where the Gaussians that lie in the volume land: their rows and, per plane, their cells.
struct Landing {
    rows: Vec<usize>,
    cells: [Vec<usize>; 3],
}

impl ProjectionFusion {
    /// The block for `features` channels per Gaussian (the cost-volume heads' context,
    /// `Prediction::features`' k), its adapter `features -> cfg.channels` under `vb`.
    pub fn new(vb: VarBuilder, cfg: &VolumeConfig, features: usize) -> Result<Self> {
        Ok(Self {
            adapter: linear(features, cfg.channels, vb.pp("adapter"))?,
            features,
            cfg: cfg.clone(),
        })
    }

    /// The additive prior of each plane, in [`Plane::ALL`] order, each `(C, rows, columns)`
    /// as [`VolumeConfig::plane_shapes`] gives, in the features' dtype. `means` `(N, 3)` are
    /// the Gaussians' centres in the bin frame, `features` `(N, k)` one row per Gaussian in
    /// the same order ([`gaussian_rows`] turns `Prediction::features` into that).
    pub fn forward(&self, means: &Tensor, features: &Tensor) -> Result<[Tensor; 3]> {
        let (n, three) = means.dims2()?;
        let (nf, k) = features.dims2()?;
        if three != 3 || nf != n || k != self.features {
            candle_core::bail!(
                "fusion takes means (N, 3) and features (N, {}), got {:?} and {:?}",
                self.features,
                means.dims(),
                features.dims()
            );
        }
        let landing = self.landing(means)?;
        let device = features.device();
        let dtype = features.dtype();
        let source = match landing.rows.len() {
            0 => None,
            m if m == n => Some(features.clone()),
            _ => Some(features.index_select(&index_tensor(&landing.rows, device)?, 0)?),
        };
        let shapes = self.cfg.plane_shapes();
        let mut out = Vec::with_capacity(3);
        for (p, (rows, columns)) in shapes.into_iter().enumerate() {
            let size = rows * columns;
            let Some(source) = &source else {
                out.push(Tensor::zeros(
                    (self.cfg.channels, rows, columns),
                    dtype,
                    device,
                )?);
                continue;
            };
            let cells = &landing.cells[p];
            let mut counts = vec![0f64; size];
            for &c in cells {
                counts[c] += 1.0;
            }
            let inverse: Vec<f64> = counts
                .iter()
                .map(|&c| if c > 0.0 { 1.0 / c } else { 0.0 })
                .collect();
            let occupied: Vec<f64> = counts.iter().map(|&c| f64::from(c > 0.0)).collect();
            // In f64, then the features' dtype: 1 / count is exact to that dtype.
            let column = |v: Vec<f64>| -> Result<Tensor> {
                Tensor::from_vec(v, (size, 1), device)?.to_dtype(dtype)
            };
            let sums = Tensor::zeros((size, k), dtype, device)?.index_add(
                &index_tensor(cells, device)?,
                source,
                0,
            )?;
            let mean = sums.broadcast_mul(&column(inverse)?)?;
            let adapted = self
                .adapter
                .forward(&mean)?
                .broadcast_mul(&column(occupied)?)?;
            let adapted = transpose_last2(&adapted.unsqueeze(0)?)?;
            out.push(adapted.reshape((self.cfg.channels, rows, columns))?);
        }
        out.try_into()
            .map_err(|_| candle_core::Error::Msg("fusion: not three planes".into()))
    }

    /// Which Gaussians lie in the volume and the cells they land in.
    fn landing(&self, means: &Tensor) -> Result<Landing> {
        let points = means
            .detach()
            .to_dtype(DType::F32)?
            .flatten_all()?
            .to_vec1::<f32>()?;
        let mut landing = Landing {
            rows: Vec::new(),
            cells: Default::default(),
        };
        for (i, p) in points.chunks_exact(3).enumerate() {
            if let Some(index) = self.cfg.cell_of([p[0], p[1], p[2]]) {
                landing.rows.push(i);
                for (p, plane) in Plane::ALL.into_iter().enumerate() {
                    landing.cells[p].push(plane_cell(&self.cfg, plane, index));
                }
            }
        }
        Ok(landing)
    }
}

/// `Prediction::features` `(V, k, Hg, Wg)` as one row per Gaussian `(V Hg Wg, k)`, in the
/// order of `Prediction::splats` (view-major, then row-major pixels).
pub fn gaussian_rows(features: &Tensor) -> Result<Tensor> {
    let (v, k, h, w) = features.dims4()?;
    transpose_last2(&features.reshape((v, k, h * w))?)?.reshape((v * h * w, k))
}
