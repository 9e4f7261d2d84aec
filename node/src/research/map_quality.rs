//! The fused global map's own quality (`stereosplat research eval-map`): a drive cut into bins
//! as the node's binner cuts it (consecutive, 8 m), each bin's first stereo pair through the
//! worker's path ([`crate::pipeline::bin_map::bin_map`]), the bin maps fused by the node's
//! [`GlobalMap`], and the fused map rendered at every (`frame_stride`-th) frame's left camera
//! and scored against the recorded image and LiDAR with the evaluation protocol's metrics
//! ([`model::eval::score_frame`]). The bin maps are made once and fused again per fusion
//! setting, so a sweep of budgets, cell sizes and keep rules costs only fusion and renders.

use glam::{DAffine3, DQuat, DVec3};
use model::bins::{make_bins, BinConfig, BinLayout};
use model::eval::{score_frame, EvalConfig, EvalError, FrameTarget, MeanScores, Raster};
use model::frame::{RgbImage, Side};
use model::kitti360::{Kitti360Error, Sequence};
use model::reconstruct::{Reconstructor, StereoView};
use renderer::GaussianSet;
use serde::Serialize;

use crate::fusion::{local_set, ExportError, FusionConfig, FusionError, GlobalMap, Keep};
use crate::pipeline::bin_map::bin_map;
use crate::pipeline::self_check::{OnCheckFail, SelfCheck};

/// Gaussians farther than this from a camera are left out of its render (they project to
/// nothing, or to less than a pixel, at the drives' sizes), metres.
const RENDER_RADIUS_M: f64 = 200.0;

/// Why the map evaluation stopped.
#[derive(Debug, thiserror::Error)]
pub enum MapEvalError {
    /// A frame could not be read.
    #[error(transparent)]
    Data(#[from] Kitti360Error),
    /// The map refused a bin or a setting.
    #[error(transparent)]
    Fusion(#[from] FusionError),
    /// The map could not be brought into a camera's frame.
    #[error(transparent)]
    Export(#[from] ExportError),
    /// A render or a metric failed.
    #[error(transparent)]
    Eval(#[from] EvalError),
    /// A render failed.
    #[error("rendering failed: {0}")]
    Render(#[from] renderer::gpu::GpuError),
}

/// One bin's published map.
#[derive(Clone, Debug)]
pub struct BinMap {
    /// The bin's number along the drive.
    pub bin_id: u64,
    /// The sequence's frame number of the bin's first frame.
    pub first_frame: u32,
    /// Bin frame (its first left camera) to world.
    pub bin_to_world: DAffine3,
    /// The map in the bin frame (empty when the reconstructor failed).
    pub set: GaussianSet,
}

/// The bin maps of `sequence` cut into consecutive bins of `bin_length_m`, each made by
/// `reconstructor` on the worker's path (self-check policy `on_fail`); `progress` gets
/// (bins done, bins in all). Also returns the drive's length, metres (sum of the frame
/// steps).
pub fn bin_maps(
    sequence: &Sequence,
    reconstructor: &mut dyn Reconstructor,
    bin_length_m: f64,
    on_fail: OnCheckFail,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(Vec<BinMap>, f64), MapEvalError> {
    let poses: Vec<DAffine3> = sequence.frames().iter().map(|f| f.left_to_world).collect();
    let config = BinConfig {
        length_m: bin_length_m,
        layout: BinLayout::Consecutive,
    };
    let bins = make_bins(&poses, &config);
    let rig = sequence.rig();
    let mut self_check = SelfCheck::new(on_fail);
    let mut maps = Vec::with_capacity(bins.len());
    for (k, bin) in bins.iter().enumerate() {
        let frame = sequence.load_frame(sequence.frames()[bin.first].index)?;
        let origin = frame.left_to_world;
        let view = StereoView {
            left: &frame.left,
            right: &frame.right,
            left_camera: rig.local_camera(origin, origin, Side::Left),
            right_camera: rig.local_camera(origin, origin, Side::Right),
        };
        let (result, _) = bin_map(reconstructor, &mut self_check, &[view]);
        maps.push(BinMap {
            bin_id: k as u64,
            first_frame: frame.index,
            bin_to_world: origin,
            set: result.unwrap_or_default(),
        });
        progress(k + 1, bins.len());
    }
    let length = poses
        .windows(2)
        .map(|w| (w[1].translation - w[0].translation).length())
        .sum();
    Ok((maps, length))
}

/// The bin maps fused in order into a map with `config`.
pub fn fuse(maps: &[BinMap], config: FusionConfig) -> Result<GlobalMap, MapEvalError> {
    let mut map = GlobalMap::new(config)?;
    for m in maps {
        map.insert_bin(m.bin_id, &m.set, m.bin_to_world)?;
    }
    Ok(map)
}

/// The map's Gaussians within `RENDER_RADIUS_M` of `camera_to_world`'s centre, in that
/// camera's frame.
pub fn set_around(map: &GlobalMap, camera_to_world: DAffine3) -> Result<GaussianSet, ExportError> {
    let centre: DVec3 = camera_to_world.translation;
    let near = map
        .gaussians()
        .map(|(_, g)| g)
        .filter(|g| (g.position - centre).length() < RENDER_RADIUS_M);
    local_set(near, camera_to_world)
}

/// The map's scores over the frames it was rendered at.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MapScores {
    /// Means over the frames (left camera).
    pub mean: MeanScores,
    /// Frames rendered.
    pub frames: usize,
}

/// The sky layers a consumer draws behind the map ([`Keep::backdrop`]), one per bin, cut
/// once: each frame is rendered with the layer of the bin it belongs to (the latest bin map
/// the node had published when the frame was taken).
#[derive(Clone, Debug)]
pub struct Backdrops {
    /// Per bin in drive order: its first frame, its pose and its far part (bin frame).
    layers: Vec<(u32, DAffine3, GaussianSet)>,
}

impl Backdrops {
    /// The far part beyond `keep` of each of `maps` (in drive order).
    pub fn new(maps: &[BinMap], keep: Keep) -> Self {
        Self {
            layers: maps
                .iter()
                .map(|m| (m.first_frame, m.bin_to_world, keep.backdrop(&m.set)))
                .collect(),
        }
    }

    /// Mean Gaussians per bin layer.
    pub fn mean_len(&self) -> f64 {
        let total: usize = self.layers.iter().map(|(_, _, l)| l.len()).sum();
        total as f64 / self.layers.len().max(1) as f64
    }

    /// The layer for frame `frame` (that of the last bin starting at or before it; empty
    /// before the first), in the frame of `camera_to_world`.
    pub fn at(&self, frame: u32, camera_to_world: DAffine3) -> GaussianSet {
        let Some((_, bin_to_world, far)) = self.layers.iter().rev().find(|l| l.0 <= frame) else {
            return GaussianSet::default();
        };
        let to_camera = camera_to_world.inverse() * *bin_to_world;
        let turn = DQuat::from_mat3(&to_camera.matrix3);
        let mut out = GaussianSet::with_capacity(far.len());
        for i in 0..far.len() {
            let mut g = far.get(i);
            g.mean = to_camera.transform_point3(g.mean.as_dvec3()).as_vec3();
            g.rotation = (turn * g.rotation.as_dquat()).normalize().as_quat();
            out.push(g);
        }
        out
    }
}

/// Renders `map` at every `frame_stride`-th frame's left camera of `sequence` (with the sky
/// layer of the frame's bin behind it when `backdrops` is given) and scores it with
/// `config`'s metrics; `progress` gets (frames done, frames in all).
pub fn score_map(
    map: &GlobalMap,
    backdrops: Option<&Backdrops>,
    sequence: &Sequence,
    raster: &mut Raster,
    config: &EvalConfig,
    frame_stride: usize,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<MapScores, MapEvalError> {
    let rig = sequence.rig();
    let frames: Vec<_> = sequence
        .frames()
        .iter()
        .step_by(frame_stride.max(1))
        .collect();
    let mut scores = Vec::with_capacity(frames.len());
    for (k, f) in frames.iter().enumerate() {
        let frame = sequence.load_frame(f.index)?;
        let pose = frame.left_to_world;
        let mut set = set_around(map, pose)?;
        if let Some(b) = backdrops {
            let far = b.at(f.index, pose);
            for i in 0..far.len() {
                set.push(far.get(i));
            }
        }
        let camera = rig.local_camera(pose, pose, Side::Left);
        let render = raster.render(&set, &camera, &config.render)?;
        let lidar = sequence.lidar_depth(f.index, Side::Left);
        let target = FrameTarget {
            frame: f.index,
            side: Side::Left,
            role: None,
            truth: &frame.left,
            unseen: None,
        };
        let score = score_frame(target, &render, lidar, config)?;
        scores.push(MeanScores::from(&score));
        progress(k + 1, frames.len());
    }
    Ok(MapScores {
        mean: MeanScores::of(&scores),
        frames: scores.len(),
    })
}

/// The map rendered from `frame`'s left camera moved `offset_m` metres along its own x axis
/// (positive: to the right), a view no recording has.
pub fn side_view(
    map: &GlobalMap,
    sequence: &Sequence,
    raster: &mut Raster,
    config: &EvalConfig,
    frame: u32,
    offset_m: f64,
) -> Result<RgbImage, MapEvalError> {
    let rig = sequence.rig();
    let pose = sequence
        .frames()
        .iter()
        .find(|f| f.index == frame)
        .map_or(DAffine3::IDENTITY, |f| f.left_to_world);
    let moved = pose * DAffine3::from_translation(DVec3::new(offset_m, 0.0, 0.0));
    let set = set_around(map, moved)?;
    let render = raster.render(
        &set,
        &rig.local_camera(moved, moved, Side::Left),
        &config.render,
    )?;
    Ok(RgbImage {
        width: render.width,
        height: render.height,
        data: render.rgb,
    })
}
