//! Tile binning: which Gaussians touch each 16x16 tile, in front-to-back order.
//!
//! The order within a tile is by camera z, ties broken by Gaussian index. The GPU reaches the
//! same order with a stable radix sort of (tile, depth bits) keys emitted in index order, so
//! the two rasterizers composite identical sequences.

use rayon::prelude::*;

use super::project::Projected;
use super::TILE_SIZE;
use crate::real::Real;

/// Per-tile lists of Gaussian indices, concatenated: tile `t` owns
/// `ids[offsets[t]..offsets[t + 1]]`, sorted front to back.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TileBins {
    /// Tiles across and down.
    pub grid: [u32; 2],
    /// Start of each tile's list in `ids`, plus the total at the end.
    pub offsets: Vec<u32>,
    /// Gaussian indices.
    pub ids: Vec<u32>,
}

impl TileBins {
    /// The Gaussians of tile `t`, front to back.
    pub fn tile(&self, t: usize) -> &[u32] {
        &self.ids[self.offsets[t] as usize..self.offsets[t + 1] as usize]
    }

    /// Number of tiles.
    pub fn tile_count(&self) -> usize {
        self.grid[0] as usize * self.grid[1] as usize
    }
}

/// Bins projected Gaussians (`None` = culled) into the tiles of a `width x height` image.
pub fn bin<T: Real>(projected: &[Option<Projected<T>>], width: u32, height: u32) -> TileBins {
    let grid = [width.div_ceil(TILE_SIZE), height.div_ceil(TILE_SIZE)];
    let tiles = grid[0] as usize * grid[1] as usize;
    let mut offsets = vec![0u32; tiles + 1];
    let each_tile = |p: &Projected<T>, f: &mut dyn FnMut(usize)| {
        for ty in p.tile_min[1]..p.tile_max[1] {
            for tx in p.tile_min[0]..p.tile_max[0] {
                f((ty * grid[0] + tx) as usize);
            }
        }
    };
    for p in projected.iter().flatten() {
        each_tile(p, &mut |t| offsets[t + 1] += 1);
    }
    for t in 0..tiles {
        offsets[t + 1] += offsets[t];
    }
    let mut cursor = offsets.clone();
    let mut ids = vec![0u32; offsets[tiles] as usize];
    for (i, p) in projected.iter().enumerate() {
        if let Some(p) = p {
            each_tile(p, &mut |t| {
                ids[cursor[t] as usize] = i as u32;
                cursor[t] += 1;
            });
        }
    }
    // Index order is already there; a stable sort by depth keeps it for ties.
    let mut lists: Vec<&mut [u32]> = Vec::with_capacity(tiles);
    let mut rest = ids.as_mut_slice();
    for t in 0..tiles {
        let (head, tail) = rest.split_at_mut((offsets[t + 1] - offsets[t]) as usize);
        lists.push(head);
        rest = tail;
    }
    lists.par_iter_mut().for_each(|list| {
        list.sort_by(|&a, &b| {
            let da = projected[a as usize].map_or(T::zero(), |p| p.depth);
            let db = projected[b as usize].map_or(T::zero(), |p| p.depth);
            da.total_cmp(&db)
        })
    });
    TileBins { grid, offsets, ids }
}
