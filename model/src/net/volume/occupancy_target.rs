//! What supervises the occupancy head: the LiDAR hits of every frame of the bin, brought
//! into the bin frame (so space the input pair could not see but a later frame scanned
//! counts), marked on the voxel grid, and a balanced binary cross-entropy on the logits
//! (occupied and free voxels weigh half each, whatever their counts; free means "no hit").

use candle_core::{Result, Tensor};
use glam::{DAffine3, DVec3};

use super::voxels::{voxel_count, voxel_index};
use super::VolumeConfig;
use crate::bins::Bin;
use crate::kitti360::Sequence;

/// A bin's LiDAR hits in the bin frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BinPoints {
    /// Every finite hit of every frame of the bin, metres in the bin frame (the first left
    /// camera's: x right, y down, z forward).
    pub points: Vec<[f32; 3]>,
    /// Frames of the bin whose scan could not be read (missing or corrupt): they add no
    /// hits, as training's depth losses treat a frame without LiDAR.
    pub frames_without_scan: usize,
}

/// The LiDAR hits of every frame of `bin` (positions into `sequence.frames()`), each scan
/// carried velodyne -> rectified camera 0 (`Calibration::velo_to_rect`) -> world (the
/// frame's `left_to_world`) -> bin frame (inverse of the first frame's), composed in `f64`
/// so drives far from the world origin lose nothing. Scans are not motion-compensated.
pub fn bin_lidar_points(sequence: &Sequence, bin: &Bin) -> BinPoints {
    let frames = sequence.frames();
    let velo_to_rect = sequence.calibration().velo_to_rect();
    let to_bin = frames[bin.first].left_to_world.inverse();
    let mut out = BinPoints::default();
    for i in bin.frames() {
        let frame = &frames[i];
        let Ok(scan) = sequence.load_lidar(frame.index) else {
            out.frames_without_scan += 1;
            continue;
        };
        let to: DAffine3 = to_bin * frame.left_to_world * velo_to_rect;
        out.points.extend(scan.iter().filter_map(|p| {
            let q = to.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            q.is_finite().then(|| q.as_vec3().to_array())
        }));
    }
    out
}

/// Per voxel (flat order): whether some point of `points` (bin frame) falls in it. Points
/// outside the volume or not finite are ignored.
pub fn occupied_voxels(cfg: &VolumeConfig, points: &[[f32; 3]]) -> Vec<bool> {
    let mut occupied = vec![false; voxel_count(cfg)];
    for p in points {
        if let Some(index) = cfg.cell_of(*p) {
            occupied[voxel_index(cfg, index)] = true;
        }
    }
    occupied
}

/// The balanced binary cross-entropy of occupancy `logits` (any shape, flat voxel order)
/// against `occupied`, over the voxels `region` allows (all when `None`; the input frusta
/// are the natural choice, as only those voxels are ever decoded): the mean loss of the
/// occupied voxels and the mean loss of the free ones, averaged (a class with no voxel in the
/// region drops out; an empty region gives 0). Computed from the logits as
/// `max(x, 0) - x t + ln(1 + exp(-|x|))`, finite for any finite logit. A scalar tensor.
pub fn occupancy_loss(
    logits: &Tensor,
    occupied: &[bool],
    region: Option<&[bool]>,
) -> Result<Tensor> {
    let n = logits.elem_count();
    if occupied.len() != n || region.is_some_and(|r| r.len() != n) {
        candle_core::bail!(
            "{n} logits, {} targets, a region of {:?}",
            occupied.len(),
            region.map(<[bool]>::len)
        );
    }
    let inside = |i: usize| region.is_none_or(|r| r[i]);
    let positives = (0..n).filter(|&i| inside(i) && occupied[i]).count();
    let negatives = (0..n).filter(|&i| inside(i) && !occupied[i]).count();
    let classes = usize::from(positives > 0) + usize::from(negatives > 0);
    let share = |count: usize| match count {
        0 => 0.0,
        c => 1.0 / (classes * c) as f64,
    };
    let (wp, wn) = (share(positives), share(negatives));
    // In f64, then the logits' dtype: the weights are exact to that dtype.
    let weights: Vec<f64> = (0..n)
        .map(|i| match (inside(i), occupied[i]) {
            (false, _) => 0.0,
            (true, true) => wp,
            (true, false) => wn,
        })
        .collect();
    let device = logits.device();
    let dtype = logits.dtype();
    let target: Vec<f32> = occupied.iter().map(|&o| f32::from(o)).collect();
    let x = logits.flatten_all()?;
    let t = Tensor::from_vec(target, n, device)?.to_dtype(dtype)?;
    let w = Tensor::from_vec(weights, n, device)?.to_dtype(dtype)?;
    let softplus = ((x.abs()?.neg()?.exp()? + 1.0)?.log()? + x.relu()?)?;
    let bce = (softplus - (&x * &t)?)?;
    (bce * w)?.sum_all()
}
