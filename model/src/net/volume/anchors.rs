//! Where the plane queries look: each plane cell's pillar of anchor points along the plane's
//! missing axis, in continuous cell coordinates and in the bin frame, and the anchors'
//! pixels in each input view's feature map (with which views see them).
//!
//! Continuous cell coordinates put the centre of cell `i` at `i` (so a plane tensor's pixel
//! `(column, row)` is its cell's centre, the convention of `ops::grid_sample`); a pillar of
//! `n` points along an axis of `cells` cells sits at `(k + 0.5) cells / n - 0.5`.

use candle_core::{DType, Device, Result, Tensor};
use glam::DVec3;
use renderer::Camera;

use super::{Plane, VolumeConfig};

/// A grid point that samples nothing: far outside every feature map (zero value and zero
/// gradient in `ops::grid_sample`), finite so no NaN ever enters a tensor.
pub(super) const NOWHERE: f64 = -1.0e6;

/// Smallest camera-frame depth (metres) at which an anchor counts as in front of a view.
const MIN_DEPTH: f64 = 1e-5;

/// Anchor points of one plane's pillars.
pub(super) fn pillar_points(cfg: &VolumeConfig, plane: Plane) -> usize {
    match plane {
        Plane::Xz => cfg.pillar_points_ground,
        _ => cfg.pillar_points_side,
    }
    .max(1)
}

/// The pillars of one plane: for each cell (row-major) its anchors in continuous cell
/// coordinates `[x, y, z]`.
pub(super) fn pillar_cells(cfg: &VolumeConfig, plane: Plane) -> Vec<[f64; 3]> {
    let (rows, cols) = plane.axes();
    let missing = plane.missing_axis();
    let (nr, nc) = cfg.plane_shapes()[plane_index(plane)];
    let n = pillar_points(cfg, plane);
    let cells = cfg.cells[missing] as f64;
    let mut out = Vec::with_capacity(nr * nc * n);
    for r in 0..nr {
        for c in 0..nc {
            for k in 0..n {
                let mut p = [0.0; 3];
                p[rows] = r as f64;
                p[cols] = c as f64;
                p[missing] = (k as f64 + 0.5) * cells / n as f64 - 0.5;
                out.push(p);
            }
        }
    }
    out
}

/// The index of `plane` in [`Plane::ALL`].
pub(super) fn plane_index(plane: Plane) -> usize {
    Plane::ALL.iter().position(|&p| p == plane).unwrap_or(0)
}

/// The bin-frame point (metres) of continuous cell coordinates `p`.
fn to_bin(cfg: &VolumeConfig, p: [f64; 3]) -> DVec3 {
    let size = cfg.cell_size();
    DVec3::from_array(std::array::from_fn(|a| {
        cfg.range_min[a] as f64 + (p[a] + 0.5) * size[a] as f64
    }))
}

/// The anchors of one plane seen from every view: feature-map pixels and visible-view counts.
/// Constant (cameras are inputs): build once per forward pass and share between layers.
#[derive(Clone, Debug)]
pub struct ViewAnchors {
    /// `(V, N, A, 2)` pixel coordinates `(x, y)` in the views' feature maps; `NOWHERE` for
    /// an anchor behind a view or outside its image.
    pub pixels: Tensor,
    /// `(N, 1)`: 1 / (number of views that see at least one of the query's anchors), 0 for a
    /// query no view sees.
    pub inverse_count: Tensor,
    /// `(N, 1)`: 1 where some view sees one of the query's anchors, else 0.
    pub seen: Tensor,
}

impl ViewAnchors {
    /// The anchors of `plane` projected into `cameras` (bin frame) and onto feature maps of
    /// `stride` image pixels per feature pixel (feature pixel `j` at image pixel `stride j`).
    pub fn new(
        cfg: &VolumeConfig,
        plane: Plane,
        cameras: &[Camera],
        stride: usize,
        dtype: DType,
        device: &Device,
    ) -> Result<Self> {
        let anchors = pillar_cells(cfg, plane);
        let a = pillar_points(cfg, plane);
        let n = anchors.len() / a;
        let s = stride as f64;
        let mut pixels = Vec::with_capacity(cameras.len() * anchors.len() * 2);
        let mut seen = vec![0u32; n];
        for camera in cameras {
            let r = camera.rotation.as_dmat3();
            let c = camera.position.as_dvec3();
            let k = camera.intrinsics;
            let (fx, fy, cx, cy) = (k.fx as f64, k.fy as f64, k.cx as f64, k.cy as f64);
            let (w, h) = (k.width as f64, k.height as f64);
            for (q, pillar) in anchors.chunks(a).enumerate() {
                let mut any = false;
                for &p in pillar {
                    let x = r * (to_bin(cfg, p) - c);
                    let (u, v) = (fx * x.x / x.z + cx, fy * x.y / x.z + cy);
                    let inside =
                        x.z > MIN_DEPTH && u >= -0.5 && u <= w - 0.5 && v >= -0.5 && v <= h - 0.5;
                    if inside {
                        pixels.extend([u / s, v / s]);
                        any = true;
                    } else {
                        pixels.extend([NOWHERE, NOWHERE]);
                    }
                }
                seen[q] += any as u32;
            }
        }
        let column = |f: &dyn Fn(u32) -> f64| {
            let data: Vec<f64> = seen.iter().map(|&k| f(k)).collect();
            Tensor::from_vec(data, (n, 1), device)?.to_dtype(dtype)
        };
        Ok(Self {
            pixels: Tensor::from_vec(pixels, (cameras.len(), n, a, 2), device)?.to_dtype(dtype)?,
            inverse_count: column(&|k| if k > 0 { 1.0 / k as f64 } else { 0.0 })?,
            seen: column(&|k| (k > 0) as u32 as f64)?,
        })
    }

    /// [`ViewAnchors::new`] for the three planes, in the order [`Plane::ALL`].
    pub fn all(
        cfg: &VolumeConfig,
        cameras: &[Camera],
        stride: usize,
        dtype: DType,
        device: &Device,
    ) -> Result<[Self; 3]> {
        let one = |p| Self::new(cfg, p, cameras, stride, dtype, device);
        Ok([one(Plane::Xz)?, one(Plane::Xy)?, one(Plane::Zy)?])
    }
}

/// The references of cross-plane attention for queries of `query` on plane `level`, as
/// `(N, P, 2)` pixel coordinates `(column, row)` of `level`'s tensor: the query's own cell
/// repeated when `level` is its own plane, else its pillar anchors projected orthogonally
/// onto `level`, `points` of them spread evenly along the pillar.
pub(super) fn plane_references(
    cfg: &VolumeConfig,
    query: Plane,
    level: Plane,
    points: usize,
    dtype: DType,
    device: &Device,
) -> Result<Tensor> {
    let anchors = pillar_cells(cfg, query);
    let a = pillar_points(cfg, query);
    let n = anchors.len() / a;
    let (rows, cols) = level.axes();
    let mut data = Vec::with_capacity(n * points * 2);
    for pillar in anchors.chunks(a) {
        for j in 0..points {
            let p = if level == query {
                // The own cell: any anchor's row and column coordinates.
                pillar[0]
            } else {
                pillar[((j as f64 + 0.5) * a as f64 / points as f64) as usize % a]
            };
            data.extend([p[cols], p[rows]]);
        }
    }
    Tensor::from_vec(data, (n, points, 2), device)?.to_dtype(dtype)
}
