//! The spatial hash: world space cut into cubes of a set edge length, each cube (cell)
//! owned by the Gaussians of one bin at a time. The fusion rule and the eviction rule both
//! act on whole cells.

use glam::DVec3;

use super::GaussianId;

/// Integer coordinates of a cell: `floor(position / cell_size)` per axis.
pub type CellKey = (i64, i64, i64);

/// The cell holding a world position (finite positions only; casts saturate far out).
pub fn cell_of(position: DVec3, cell_size: f64) -> CellKey {
    let k = (position / cell_size).floor();
    (k.x as i64, k.y as i64, k.z as i64)
}

/// The centre of a cell in world coordinates, metres.
pub fn cell_centre(key: CellKey, cell_size: f64) -> DVec3 {
    (DVec3::new(key.0 as f64, key.1 as f64, key.2 as f64) + 0.5) * cell_size
}

/// The Gaussians of one occupied cell.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Cell {
    /// Ids of the Gaussians in the cell, in the order they were inserted.
    pub ids: Vec<GaussianId>,
    /// The highest confidence among them: what a new bin must beat to take the cell over.
    pub max_confidence: f32,
}

impl Cell {
    /// Adds a Gaussian with confidence `confidence` to the cell.
    pub fn push(&mut self, id: GaussianId, confidence: f32) {
        if self.ids.is_empty() || confidence > self.max_confidence {
            self.max_confidence = confidence;
        }
        self.ids.push(id);
    }
}

/// The order in which cells are evicted when the map is over budget: farthest from
/// `anchor` (the latest bin's position) first, ties by cell key, so the order is the same
/// on every run whatever the hash map's iteration order.
pub fn eviction_order(
    keys: impl IntoIterator<Item = CellKey>,
    anchor: DVec3,
    cell_size: f64,
) -> Vec<CellKey> {
    let mut keyed: Vec<(f64, CellKey)> = keys
        .into_iter()
        .map(|k| (cell_centre(k, cell_size).distance_squared(anchor), k))
        .collect();
    keyed.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    keyed.into_iter().map(|(_, k)| k).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_floor_towards_negative_infinity() {
        assert_eq!(cell_of(DVec3::new(0.24, -0.01, 0.25), 0.25), (0, -1, 1));
        assert_eq!(
            cell_centre((0, -1, 1), 0.25),
            DVec3::new(0.125, -0.125, 0.375)
        );
    }

    #[test]
    fn farthest_cells_come_first() {
        let order = eviction_order(
            [(0, 0, 0), (5, 0, 0), (-5, 0, 0), (2, 0, 0)],
            DVec3::splat(0.5),
            1.0,
        );
        assert_eq!(order, vec![(-5, 0, 0), (5, 0, 0), (2, 0, 0), (0, 0, 0)]);
    }
}
