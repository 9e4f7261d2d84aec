//! The spatial hash: world space cut into cubes of a set edge length, each cube (cell)
//! owned by the Gaussians of one bin at a time. The fusion rule and the eviction rule both
//! act on whole cells.

use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};

use glam::{DVec2, DVec3};

use super::GaussianId;

/// Ground size of a column of the cell index, metres: the granularity of region queries.
const COLUMN_M: f64 = 16.0;

/// The side of a ground column of the cell index for cells of `cell_size`, metres: about
/// [`COLUMN_M`], a whole number of cells.
pub fn column_side(cell_size: f64) -> f64 {
    cells_per_column(cell_size) as f64 * cell_size
}

/// Cells per side of a ground column, for cells of `cell_size`.
pub fn cells_per_column(cell_size: f64) -> i64 {
    ((COLUMN_M / cell_size).round() as i64).max(1)
}

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

/// One ground column of the index: its occupied cells and how many Gaussians they hold, so
/// counting a region's Gaussians costs its columns, not its cells.
#[derive(Clone, Debug, Default)]
struct Column {
    keys: HashSet<CellKey>,
    gaussians: u64,
}

/// The occupied cells, with an index of them by ground column (x-y squares of about
/// [`COLUMN_M`], every height) so a region of the ground is found without visiting the map.
#[derive(Clone, Debug)]
pub struct CellIndex {
    cells: HashMap<CellKey, Cell>,
    columns: HashMap<(i64, i64), Column>,
    /// Cells per column side.
    per_column: i64,
    cell_size: f64,
}

impl CellIndex {
    /// An empty index of cells of `cell_size` metres.
    pub fn new(cell_size: f64) -> Self {
        Self {
            cells: HashMap::default(),
            columns: HashMap::default(),
            per_column: cells_per_column(cell_size),
            cell_size,
        }
    }

    fn column(&self, key: CellKey) -> (i64, i64) {
        (
            key.0.div_euclid(self.per_column),
            key.1.div_euclid(self.per_column),
        )
    }

    /// Occupied cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// The cell at `key`, if occupied.
    pub fn get(&self, key: &CellKey) -> Option<&Cell> {
        self.cells.get(key)
    }

    /// Whether the cell at `key` is occupied.
    pub fn contains(&self, key: &CellKey) -> bool {
        self.cells.contains_key(key)
    }

    /// Adds Gaussian `id` with `confidence` to the cell at `key`.
    pub fn push(&mut self, key: CellKey, id: GaussianId, confidence: f32) {
        let column = self.column(key);
        let column = self.columns.entry(column).or_default();
        let cell = self.cells.entry(key).or_default();
        if cell.ids.is_empty() {
            column.keys.insert(key);
        }
        column.gaussians += 1;
        cell.push(id, confidence);
    }

    /// Empties the cell at `key`; its ids (none when it was empty).
    pub fn remove(&mut self, key: CellKey) -> Vec<GaussianId> {
        let Some(cell) = self.cells.remove(&key) else {
            return Vec::new();
        };
        let column = self.column(key);
        if let Some(c) = self.columns.get_mut(&column) {
            c.keys.remove(&key);
            c.gaussians = c.gaussians.saturating_sub(cell.ids.len() as u64);
            if c.keys.is_empty() {
                self.columns.remove(&column);
            }
        }
        cell.ids
    }

    /// Removes Gaussian `id` from the cell at `key`; the cell's highest confidence is
    /// recomputed from what is left with `confidence_of`.
    pub fn remove_id(
        &mut self,
        key: CellKey,
        id: GaussianId,
        confidence_of: impl Fn(GaussianId) -> Option<f32>,
    ) {
        let column = self.column(key);
        let Some(cell) = self.cells.get_mut(&key) else {
            return;
        };
        let before = cell.ids.len();
        cell.ids.retain(|i| *i != id);
        let gone = (before - cell.ids.len()) as u64;
        if let Some(c) = self.columns.get_mut(&column) {
            c.gaussians = c.gaussians.saturating_sub(gone);
        }
        if cell.ids.is_empty() {
            self.remove(key);
            return;
        }
        cell.max_confidence = cell
            .ids
            .iter()
            .filter_map(|&i| confidence_of(i))
            .fold(f32::NEG_INFINITY, f32::max);
    }

    /// The ids in every cell whose ground column meets the box `min`-`max` (x-y, metres),
    /// in no set order: a superset of the Gaussians whose centres lie in the box, found by
    /// visiting only the columns it covers.
    pub fn ids_near(&self, min: DVec2, max: DVec2) -> Vec<GaussianId> {
        let side = self.per_column as f64 * self.cell_size;
        let lo = (min / side).floor();
        let hi = (max / side).floor();
        let mut ids = Vec::new();
        if !(lo.is_finite() && hi.is_finite()) {
            return ids;
        }
        // Casts saturate far out; a box wider than the occupied columns visits those
        // columns instead of the box's.
        let (x0, x1, y0, y1) = (lo.x as i64, hi.x as i64, lo.y as i64, hi.y as i64);
        let span = (x1.saturating_sub(x0).saturating_add(1))
            .saturating_mul(y1.saturating_sub(y0).saturating_add(1));
        let mut take = |column: &Column| {
            column
                .keys
                .iter()
                .for_each(|k| ids.extend(&self.cells[k].ids));
        };
        if span > self.columns.len() as i64 {
            for (&(cx, cy), column) in &self.columns {
                if (x0..=x1).contains(&cx) && (y0..=y1).contains(&cy) {
                    take(column);
                }
            }
        } else {
            for cx in x0..=x1 {
                for cy in y0..=y1 {
                    if let Some(column) = self.columns.get(&(cx, cy)) {
                        take(column);
                    }
                }
            }
        }
        ids
    }

    /// The ground columns, farthest (column centre, on the ground) from `anchor` first, ties
    /// by column key: the order in which the budget evicts them. Costs the number of
    /// columns, not of cells.
    pub fn columns_farthest_first(&self, anchor: DVec3) -> Vec<(i64, i64)> {
        let side = self.per_column as f64 * self.cell_size;
        let mut keyed: Vec<(f64, (i64, i64))> = self
            .columns
            .keys()
            .map(|&(x, y)| {
                let centre = (DVec2::new(x as f64, y as f64) + 0.5) * side;
                (centre.distance_squared(anchor.truncate()), (x, y))
            })
            .collect();
        keyed.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        keyed.into_iter().map(|(_, c)| c).collect()
    }

    /// Every occupied ground column with the Gaussians its cells hold, in no set order:
    /// kept as cells fill and empty, so this costs the columns, not the cells.
    pub fn column_counts(&self) -> impl Iterator<Item = ((i64, i64), u64)> + '_ {
        self.columns
            .iter()
            .map(|(&column, c)| (column, c.gaussians))
    }

    /// The occupied cells of a ground column, in no set order.
    pub fn column_cells(&self, column: (i64, i64)) -> Vec<CellKey> {
        self.columns
            .get(&column)
            .map(|c| c.keys.iter().copied().collect())
            .unwrap_or_default()
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

    #[test]
    fn column_counts_follow_every_push_and_removal() {
        let mut index = CellIndex::new(0.2);
        // Two cells in one 16 m column, one in the next column along x.
        index.push((0, 0, 0), GaussianId(1), 0.5);
        index.push((0, 0, 0), GaussianId(2), 0.7);
        index.push((3, 5, -2), GaussianId(3), 0.1);
        index.push((80, 0, 0), GaussianId(4), 0.2);
        let counts = |i: &CellIndex| {
            let mut v: Vec<_> = i.column_counts().collect();
            v.sort();
            v
        };
        assert_eq!(counts(&index), vec![((0, 0), 3), ((1, 0), 1)]);
        index.remove_id((0, 0, 0), GaussianId(1), |_| Some(0.7));
        index.remove_id((0, 0, 0), GaussianId(99), |_| Some(0.7));
        assert_eq!(counts(&index), vec![((0, 0), 2), ((1, 0), 1)]);
        assert_eq!(index.remove((80, 0, 0)), vec![GaussianId(4)]);
        assert_eq!(index.remove((80, 0, 0)), Vec::<GaussianId>::new());
        assert_eq!(counts(&index), vec![((0, 0), 2)]);
        index.remove_id((0, 0, 0), GaussianId(2), |_| None);
        index.remove((3, 5, -2));
        assert_eq!(counts(&index), vec![]);
    }
}
