//! How voxels and plane cells are numbered, so the occupancy grid, the selection, the decoder
//! and the fusion agree: the occupancy grid is an `(X, Y, Z)` tensor, voxel `[x, y, z]` at
//! flat index `(x Y + y) Z + z`; a plane cell `(row, column)` at flat index
//! `row columns + column` of the plane's `(C, rows, columns)` tensor reshaped to
//! `(C, rows columns)`.

use candle_core::{DType, Device, Result, Tensor};

use super::{Plane, VolumeConfig};

/// Voxels of the grid, `X Y Z`.
pub fn voxel_count(cfg: &VolumeConfig) -> usize {
    cfg.cells.iter().product()
}

/// The flat index of voxel `[x, y, z]`.
pub fn voxel_index(cfg: &VolumeConfig, index: [usize; 3]) -> usize {
    let [_, y, z] = cfg.cells;
    (index[0] * y + index[1]) * z + index[2]
}

/// The voxel `[x, y, z]` at flat index `flat` (the inverse of [`voxel_index`]).
pub fn voxel_at(cfg: &VolumeConfig, flat: usize) -> [usize; 3] {
    let [_, y, z] = cfg.cells;
    [flat / (y * z), (flat / z) % y, flat % z]
}

/// The flat cell of `plane` that voxel `index` projects onto.
pub fn plane_cell(cfg: &VolumeConfig, plane: Plane, index: [usize; 3]) -> usize {
    let (row, column) = plane.cell_of_voxel(index);
    let (r, c) = plane.axes();
    debug_assert!(row < cfg.cells[r] && column < cfg.cells[c]);
    row * cfg.cells[c] + column
}

/// Flat indices as a `u32` index tensor (what `index_select` and `index_add` take).
pub fn index_tensor(indices: &[usize], device: &Device) -> Result<Tensor> {
    let ids: Vec<u32> = indices.iter().map(|&i| i as u32).collect();
    Tensor::from_vec(ids, indices.len(), device)
}

/// Checks that `planes` have the shapes [`VolumeConfig::plane_shapes`] gives with the
/// configured channels, and returns their dtype.
pub fn check_planes(cfg: &VolumeConfig, planes: &[Tensor; 3]) -> Result<DType> {
    for (plane, (rows, columns)) in planes.iter().zip(cfg.plane_shapes()) {
        let expected = [cfg.channels, rows, columns];
        if plane.dims() != expected {
            candle_core::bail!("plane {:?} is not {expected:?}", plane.dims());
        }
    }
    Ok(planes[0].dtype())
}
