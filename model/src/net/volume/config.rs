//! Sizes of the 3D-volume (triplane) branch (paper section 3.2.2): the volume's extent in the
//! bin frame, its cells, the attention sizes and how many voxels are decoded.

use serde::{Deserialize, Serialize};

/// One encoder layer of the triplane transformer (TPVFormer's layer kinds).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VolumeLayer {
    /// Cross-plane attention, then cross-image attention, then the feed-forward block.
    Hybrid,
    /// Cross-plane attention and the feed-forward block only (no image sampling).
    #[serde(rename = "self")]
    SelfOnly,
}

/// Every size of the volume branch. Axes follow the bin frame (the first left camera's):
/// x right, y down, z forward; index 0, 1, 2 of each array is x, y, z.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VolumeConfig {
    /// Near corner of the volume, metres in the bin frame.
    pub range_min: [f32; 3],
    /// Far corner of the volume, metres in the bin frame.
    pub range_max: [f32; 3],
    /// Cells along x, y and z (cell size = extent / cells, per axis).
    pub cells: [usize; 3],
    /// Channels of the plane queries (the paper's embedding size).
    pub channels: usize,
    /// Attention heads of both deformable attentions.
    pub heads: usize,
    /// Hidden channels of each layer's feed-forward block.
    pub ffn_channels: usize,
    /// The encoder's layers, in order.
    pub layers: Vec<VolumeLayer>,
    /// Anchor points of a ground-plane (XZ) query's pillar along y.
    pub pillar_points_ground: usize,
    /// Anchor points of a front (XY) or side (ZY) plane query's pillar along its missing axis.
    pub pillar_points_side: usize,
    /// Learned sampling offsets per anchor and head in cross-image attention.
    pub offsets_per_anchor: usize,
    /// Sampling points per head per plane in cross-plane attention.
    pub plane_points: usize,
    /// Frequencies M of the sinusoidal pose code.
    pub pose_frequencies: usize,
    /// Base b of the pose code's frequencies, `omega_m = 2 pi b^(-(m-1)/(M-1))`.
    pub pose_base: f32,
    /// Translation scale of the pose code (1 / metres): the translation is multiplied by it,
    /// so it is the paper's `1 / s_t` (0.1: 10 m becomes 1).
    pub pose_translation_scale: f32,
    /// Rotation scale of the pose code (1 / radians): the log map is multiplied by it (the
    /// paper's `1 / s_r`).
    pub pose_rotation_scale: f32,
    /// Whether the pose code also carries the raw pose (the paper's gamma switch).
    pub pose_raw: bool,
    /// Gaussians decoded per voxel (V).
    pub gaussians_per_voxel: usize,
    /// At most this many voxels are decoded per bin (highest occupancy first, only voxels
    /// inside some input frustum): Gaussian counts follow the scene, not the grid.
    pub top_k: usize,
}

impl Default for VolumeConfig {
    /// `tiny`'s volume: what configurations written before the branch existed get.
    fn default() -> Self {
        Self::tiny()
    }
}

impl VolumeConfig {
    /// `tiny`: x +-16 m, y -5.5..2.5 m, z 0..48 m in 2/3 m cells (48 x 12 x 72), 64 channels,
    /// 4 heads, layers [hybrid, self].
    pub fn tiny() -> Self {
        Self {
            range_min: [-16.0, -5.5, 0.0],
            range_max: [16.0, 2.5, 48.0],
            cells: [48, 12, 72],
            channels: 64,
            heads: 4,
            ffn_channels: 128,
            layers: vec![VolumeLayer::Hybrid, VolumeLayer::SelfOnly],
            pillar_points_ground: 4,
            pillar_points_side: 8,
            offsets_per_anchor: 2,
            plane_points: 4,
            pose_frequencies: 4,
            pose_base: 100.0,
            pose_translation_scale: 0.1,
            pose_rotation_scale: 1.0,
            pose_raw: true,
            gaussians_per_voxel: 2,
            top_k: 4096,
        }
    }

    /// `small`: the same extent in 1/2 m cells (64 x 16 x 96), 96 channels, 8 heads.
    pub fn small() -> Self {
        Self {
            cells: [64, 16, 96],
            channels: 96,
            heads: 8,
            ffn_channels: 192,
            layers: vec![
                VolumeLayer::Hybrid,
                VolumeLayer::Hybrid,
                VolumeLayer::SelfOnly,
            ],
            pillar_points_ground: 8,
            pillar_points_side: 16,
            plane_points: 8,
            top_k: 16_384,
            ..Self::tiny()
        }
    }

    /// The paper's (and OmniScene's): x and z +-50 m, 3 m below to 12 m above the camera,
    /// 192 x 16 x 192 cells, 128 channels, 8 heads, FFN 256, layers [hybrid, hybrid, self],
    /// pillars of 8 and 16 points, 32 points per plane.
    pub fn paper() -> Self {
        Self {
            range_min: [-50.0, -12.0, -50.0],
            range_max: [50.0, 3.0, 50.0],
            cells: [192, 16, 192],
            channels: 128,
            heads: 8,
            ffn_channels: 256,
            layers: vec![
                VolumeLayer::Hybrid,
                VolumeLayer::Hybrid,
                VolumeLayer::SelfOnly,
            ],
            pillar_points_ground: 8,
            pillar_points_side: 16,
            plane_points: 32,
            top_k: 200_000,
            ..Self::tiny()
        }
    }

    /// Cell size along each axis, metres.
    pub fn cell_size(&self) -> [f32; 3] {
        std::array::from_fn(|a| (self.range_max[a] - self.range_min[a]) / self.cells[a] as f32)
    }

    /// Centre of cell `index` (x, y, z cell indices) in the bin frame.
    pub fn cell_centre(&self, index: [usize; 3]) -> [f32; 3] {
        let size = self.cell_size();
        std::array::from_fn(|a| self.range_min[a] + (index[a] as f32 + 0.5) * size[a])
    }

    /// The cell holding bin-frame point `p`, or `None` outside the volume (or not finite).
    pub fn cell_of(&self, p: [f32; 3]) -> Option<[usize; 3]> {
        let size = self.cell_size();
        let mut index = [0; 3];
        for a in 0..3 {
            let t = (p[a] - self.range_min[a]) / size[a];
            if !(t >= 0.0 && t < self.cells[a] as f32) {
                return None;
            }
            index[a] = (t as usize).min(self.cells[a] - 1);
        }
        Some(index)
    }

    /// The shape `(rows, columns)` of each plane, in the order [`Plane::ALL`]:
    /// XZ `(z, x)`, XY `(y, x)`, ZY `(y, z)`.
    pub fn plane_shapes(&self) -> [(usize, usize); 3] {
        let [x, y, z] = self.cells;
        [(z, x), (y, x), (y, z)]
    }
}

/// One of the three axis-aligned planes of the triplane. A plane's tensor is `(C, rows,
/// columns)` with the shape [`VolumeConfig::plane_shapes`] gives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plane {
    /// The ground plane: rows along z (forward), columns along x (right); missing axis y.
    Xz,
    /// The front plane: rows along y (down), columns along x; missing axis z.
    Xy,
    /// The side plane: rows along y, columns along z; missing axis x.
    Zy,
}

impl Plane {
    /// The planes in the order every plane array and tensor list uses.
    pub const ALL: [Plane; 3] = [Plane::Xz, Plane::Xy, Plane::Zy];

    /// The axes (0 = x, 1 = y, 2 = z) of the plane's rows and columns.
    pub fn axes(self) -> (usize, usize) {
        match self {
            Plane::Xz => (2, 0),
            Plane::Xy => (1, 0),
            Plane::Zy => (1, 2),
        }
    }

    /// The axis the plane collapses (a query's pillar runs along it).
    pub fn missing_axis(self) -> usize {
        match self {
            Plane::Xz => 1,
            Plane::Xy => 2,
            Plane::Zy => 0,
        }
    }

    /// The cell of this plane that voxel `index` (x, y, z) projects onto, `(row, column)`.
    pub fn cell_of_voxel(self, index: [usize; 3]) -> (usize, usize) {
        let (r, c) = self.axes();
        (index[r], index[c])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_cover_their_extent_with_whole_cells() {
        let tiny = VolumeConfig::tiny();
        let size = tiny.cell_size();
        for s in size {
            assert!((s - 2.0 / 3.0).abs() < 1e-5, "{size:?}");
        }
        assert_eq!(tiny.plane_shapes(), [(72, 48), (12, 48), (12, 72)]);
        let paper = VolumeConfig::paper();
        assert_eq!(paper.cells, [192, 16, 192]);
        assert!((paper.cell_size()[0] - 100.0 / 192.0).abs() < 1e-6);
    }

    #[test]
    fn points_map_to_cells_and_back() {
        let cfg = VolumeConfig::tiny();
        let p = [0.1, 1.55, 10.0];
        let index = cfg.cell_of(p).unwrap();
        let c = cfg.cell_centre(index);
        let size = cfg.cell_size();
        for a in 0..3 {
            assert!((c[a] - p[a]).abs() <= size[a] / 2.0 + 1e-5);
        }
        assert_eq!(cfg.cell_of([0.0, 0.0, -0.01]), None);
        assert_eq!(cfg.cell_of([16.0, 0.0, 1.0]), None);
        assert_eq!(cfg.cell_of([f32::NAN, 0.0, 1.0]), None);
        assert_eq!(cfg.cell_of([0.0, 0.0, 1e30]), None);
        assert_eq!(Plane::Xz.cell_of_voxel(index), (index[2], index[0]));
        assert_eq!(Plane::Zy.cell_of_voxel([1, 2, 3]), (2, 3));
    }
}
