//! Training samples from bins (paper section 3.2.4): the input is a random subset of a bin's
//! stereo pairs, `m ~ U{1..K}` (stochastic view subsampling; switched off, the bin's first
//! pair), the targets are other frames of the same bin, with their sparse LiDAR depth.

use std::path::{Path, PathBuf};

use candle_core::{Device, Tensor};
use glam::DAffine3;
use rand::seq::index::sample;
use rand::Rng;
use renderer::Camera;

use crate::bins::{make_bins, Bin, BinConfig};
use crate::frame::{DepthMap, RgbImage, Side, StereoFrame, StereoRig};
use crate::kitti360::{Kitti360Error, Sequence};
use crate::net::every_nth_pixel;
use crate::net::volume::{bin_lidar_points, occupied_voxels, VolumeConfig};
use crate::reconstruct::StereoView;

/// Why training data could not be read.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// The layout could not be read.
    #[error(transparent)]
    Kitti360(#[from] Kitti360Error),
    /// The root holds no usable bin.
    #[error("no bin of {length} m in any sequence under {root}")]
    NoBins {
        /// The data root.
        root: String,
        /// The bin length.
        length: f64,
    },
    /// No root was given.
    #[error("no training data root given")]
    NoRoots,
    /// A tensor could not be built.
    #[error(transparent)]
    Tensor(#[from] candle_core::Error),
    /// The views do not fit the network (sizes).
    #[error(transparent)]
    Views(#[from] crate::reconstruct::ReconstructError),
}

/// How samples are drawn.
#[derive(Clone, Debug)]
pub struct SampleConfig {
    /// At most this many input pairs (the paper's K).
    pub max_pairs: usize,
    /// Draw the number and placement of input pairs at random (the paper's stochastic view
    /// subsampling); off, the input is the bin's first pair.
    pub subsample_views: bool,
    /// Target frames per sample (each with a random camera of the pair).
    pub targets: usize,
    /// Stride of the estimated depth the depth loss compares against LiDAR.
    pub gaussian_stride: usize,
    /// The volume branch's grid when the network has the branch: samples then carry the
    /// occupied voxels (LiDAR of the whole bin) and each target's in-volume pixels.
    pub volume: Option<VolumeConfig>,
}

/// A frame to render and compare with.
pub struct Target {
    /// Its camera in the bin's frame.
    pub camera: Camera,
    /// The recorded image, `(3, H, W)`.
    pub image: Tensor,
    /// Sparse LiDAR depth, `(H, W)`, 0 where none.
    pub depth: Tensor,
    /// `(H, W)`, 1 where the pixel's true surface point lies inside the volume (exact depth
    /// where the drive has it, else LiDAR), 0 elsewhere; `None` without a volume branch.
    pub in_volume: Option<Tensor>,
}

/// One training sample.
pub struct Sample {
    /// Input images `(2m, 3, H, W)`.
    pub images: Tensor,
    /// Their cameras in the bin's frame.
    pub cameras: Vec<Camera>,
    /// LiDAR depth of the inputs at the Gaussians' pixels, `(2m, 1, Hg, Wg)`, 0 where none.
    pub input_depth: Tensor,
    /// The frames to render.
    pub targets: Vec<Target>,
    /// Per voxel of the volume (flat order): whether a LiDAR hit of some frame of the bin
    /// falls in it; `None` without a volume branch.
    pub occupied: Option<Vec<bool>>,
}

/// One data root of a training mix and how its sequences are cut into bins: streets, desks
/// and rooms move metres, centimetres and decimetres per frame, so each kind needs its own
/// bin length.
#[derive(Clone, Debug)]
pub struct DataRoot {
    /// A KITTI-360-layout root, or a folder of them.
    pub path: PathBuf,
    /// How its sequences are cut.
    pub bins: BinConfig,
}

impl DataRoot {
    /// `path` cut into the default bins (8 m, streets).
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            bins: BinConfig::default(),
        }
    }
}

/// Every bin of every sequence under one or more roots. A sample draws a root uniformly
/// (so a mix is balanced by kind however many bins each kind cuts into), then a bin of it.
pub struct TrainingSet {
    sequences: Vec<Sequence>,
    /// Per root, its bins with the index of their sequence.
    roots: Vec<Vec<(usize, Bin)>>,
}

impl TrainingSet {
    /// Opens every sequence under each root (read at `resize` if given: width, height) and
    /// cuts it into the root's bins. A root is one KITTI-360-layout root, or a folder of
    /// them (each subfolder with its own `calibration/`: drives of different rigs, as the
    /// domain randomisation writes them). A root without a bin is an error.
    pub fn open(roots: &[DataRoot], resize: Option<(u32, u32)>) -> Result<Self, DataError> {
        let mut sequences = Vec::new();
        let mut all = Vec::with_capacity(roots.len());
        for data in roots {
            let mut bins = Vec::new();
            for (root, name) in sequences_under(&data.path)? {
                let mut sequence = Sequence::open(&root, &name)?;
                if let Some((w, h)) = resize {
                    sequence = sequence.with_resolution(w, h);
                }
                let poses: Vec<_> = sequence.frames().iter().map(|f| f.left_to_world).collect();
                bins.extend(
                    make_bins(&poses, &data.bins)
                        .into_iter()
                        .map(|b| (sequences.len(), b)),
                );
                sequences.push(sequence);
            }
            if bins.is_empty() {
                return Err(DataError::NoBins {
                    root: data.path.display().to_string(),
                    length: data.bins.length_m,
                });
            }
            all.push(bins);
        }
        if all.is_empty() {
            return Err(DataError::NoRoots);
        }
        Ok(Self {
            sequences,
            roots: all,
        })
    }

    /// How many bins there are, over all roots.
    pub fn len(&self) -> usize {
        self.roots.iter().map(Vec::len).sum()
    }

    /// Whether there are none (never, once opened).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bin `i` (of [`Self::len`], the roots' bins in order) with the sequence it was cut
    /// from. Panics when `i` is not below [`Self::len`], as indexing does.
    pub fn bin(&self, mut i: usize) -> (&Sequence, Bin) {
        for bins in &self.roots {
            if let Some(&(s, bin)) = bins.get(i) {
                return (&self.sequences[s], bin);
            }
            i -= bins.len();
        }
        panic!("bin index past the training set's {} bins", self.len())
    }

    /// Draws a sample with `rng`.
    pub fn sample(
        &self,
        rng: &mut impl Rng,
        cfg: &SampleConfig,
        device: &Device,
    ) -> Result<Sample, DataError> {
        // One root draws nothing for the root, so its sample stream is that of a set
        // of one root.
        let bins = match self.roots.len() {
            1 => &self.roots[0],
            n => &self.roots[rng.random_range(0..n)],
        };
        let (s, bin) = bins[rng.random_range(0..bins.len())];
        let sequence = &self.sequences[s];
        let frames: Vec<usize> = bin.frames().collect();
        let inputs: Vec<usize> = if cfg.subsample_views {
            let k = cfg.max_pairs.min(frames.len() - 1).max(1);
            let m = rng.random_range(1..=k);
            let mut picked: Vec<usize> = sample(rng, frames.len(), m)
                .into_iter()
                .map(|i| frames[i])
                .collect();
            picked.sort_unstable();
            picked
        } else {
            vec![bin.first]
        };
        let chosen = draw_targets(rng, &frames, &inputs, cfg.targets);

        let bin_inputs = BinInputs::load(sequence, &bin, &inputs)?;
        let input_frames = &bin_inputs.frames;
        let (images, cameras) = crate::net::images_and_cameras(&bin_inputs.views(), device)?;
        let mut depths = Vec::with_capacity(cameras.len());
        for f in input_frames {
            for side in [Side::Left, Side::Right] {
                depths.push(depth_tensor(&lidar_or_empty(sequence, f, side), device)?);
            }
        }
        let input_depth = every_nth_pixel(&Tensor::stack(&depths, 0)?, cfg.gaussian_stride)?;

        let mut targets = Vec::with_capacity(chosen.len());
        for i in chosen {
            let frame = sequence.load_frame(sequence.frames()[i].index)?;
            let side = if rng.random_bool(0.5) {
                Side::Left
            } else {
                Side::Right
            };
            let image = match side {
                Side::Left => &frame.left,
                Side::Right => &frame.right,
            };
            let camera = bin_inputs.camera(&frame, side);
            let lidar = lidar_or_empty(sequence, &frame, side);
            let in_volume = match &cfg.volume {
                Some(volume) => {
                    let truth = match sequence.exact_depth(frame.index, side) {
                        Ok(Some(exact)) => exact,
                        _ => lidar.clone(),
                    };
                    Some(in_volume_mask(volume, &camera, &truth, device)?)
                }
                None => None,
            };
            targets.push(Target {
                camera,
                image: image_tensor(image, device)?,
                depth: depth_tensor(&lidar, device)?.squeeze(0)?,
                in_volume,
            });
        }
        let occupied = cfg
            .volume
            .as_ref()
            .map(|v| occupied_voxels(v, &bin_lidar_points(sequence, &bin).points));
        Ok(Sample {
            images,
            cameras,
            input_depth,
            targets,
            occupied,
        })
    }
}

/// Up to `n` frames of `frames` that are not `inputs`, drawn with `rng`: a sample's targets.
pub(crate) fn draw_targets(
    rng: &mut impl Rng,
    frames: &[usize],
    inputs: &[usize],
    n: usize,
) -> Vec<usize> {
    let rest: Vec<usize> = frames
        .iter()
        .copied()
        .filter(|f| !inputs.contains(f))
        .collect();
    sample(rng, rest.len(), n.min(rest.len()))
        .into_iter()
        .map(|i| rest[i])
        .collect()
}

/// A bin's input frames, loaded, with the bin frame (its first left camera) and the rig.
pub(crate) struct BinInputs {
    /// The input frames in the order asked for.
    pub frames: Vec<StereoFrame>,
    origin: DAffine3,
    rig: StereoRig,
}

impl BinInputs {
    /// Loads frames `inputs` (positions in `sequence.frames()`) of `bin`.
    pub fn load(sequence: &Sequence, bin: &Bin, inputs: &[usize]) -> Result<Self, Kitti360Error> {
        let poses = sequence.frames();
        Ok(Self {
            frames: inputs
                .iter()
                .map(|&i| sequence.load_frame(poses[i].index))
                .collect::<Result<_, _>>()?,
            origin: poses[bin.first].left_to_world,
            rig: sequence.rig(),
        })
    }

    /// The camera of `frame`'s `side` in the bin frame.
    pub fn camera(&self, frame: &StereoFrame, side: Side) -> Camera {
        self.rig
            .local_camera(self.origin, frame.left_to_world, side)
    }

    /// The input frames as stereo views with cameras in the bin frame.
    pub fn views(&self) -> Vec<StereoView<'_>> {
        self.frames
            .iter()
            .map(|f| StereoView {
                left: &f.left,
                right: &f.right,
                left_camera: self.camera(f, Side::Left),
                right_camera: self.camera(f, Side::Right),
            })
            .collect()
    }
}

/// `(H, W)`: 1 where `depth` (z in `camera`, 0 where unknown) puts the pixel's surface
/// point inside the volume of `cfg` (bin frame), else 0.
fn in_volume_mask(
    cfg: &VolumeConfig,
    camera: &Camera,
    depth: &DepthMap,
    device: &Device,
) -> candle_core::Result<Tensor> {
    let k = camera.intrinsics;
    let to_bin = camera.rotation.transpose();
    let (w, h) = (depth.width as usize, depth.height as usize);
    let mut mask = vec![0f32; w * h];
    for (i, (&z, m)) in depth.data.iter().zip(&mut mask).enumerate() {
        if !(z.is_finite() && z > 0.0) {
            continue;
        }
        let (u, v) = ((i % w) as f32, (i / w) as f32);
        let p = glam::Vec3::new((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z);
        let q = to_bin * p + camera.position;
        if cfg.cell_of(q.to_array()).is_some() {
            *m = 1.0;
        }
    }
    Tensor::from_vec(mask, (h, w), device)
}

/// Every (root, sequence name) under `root`: its own sequences if it is a KITTI-360 root,
/// else those of each subfolder that is one (sorted, so the order is reproducible).
fn sequences_under(root: &Path) -> Result<Vec<(std::path::PathBuf, String)>, DataError> {
    let roots = match root.join("calibration").is_dir() {
        true => vec![root.to_path_buf()],
        false => {
            let mut roots: Vec<_> = std::fs::read_dir(root)
                .map_err(|e| Kitti360Error::io(root, e))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.join("calibration").is_dir())
                .collect();
            roots.sort();
            roots
        }
    };
    let mut all = Vec::new();
    for r in roots {
        all.extend(Sequence::list(&r)?.into_iter().map(|n| (r.clone(), n)));
    }
    Ok(all)
}

/// The frame's LiDAR depth, or an empty map when it has none (its depth losses vanish).
fn lidar_or_empty(sequence: &Sequence, frame: &StereoFrame, side: Side) -> DepthMap {
    sequence
        .lidar_depth(frame.index, side)
        .unwrap_or_else(|_| DepthMap::empty(frame.left.width, frame.left.height))
}

/// An image as `(3, H, W)`.
pub fn image_tensor(image: &RgbImage, device: &Device) -> candle_core::Result<Tensor> {
    Tensor::from_vec(
        image.data.clone(),
        (image.height as usize, image.width as usize, 3),
        device,
    )?
    .permute((2, 0, 1))?
    .contiguous()
}

/// A depth map as `(1, H, W)`, non-finite values as 0 (no measurement).
pub fn depth_tensor(depth: &DepthMap, device: &Device) -> candle_core::Result<Tensor> {
    let data = depth
        .data
        .iter()
        .map(|&d| if d.is_finite() && d > 0.0 { d } else { 0.0 })
        .collect();
    Tensor::from_vec(
        data,
        (1, depth.height as usize, depth.width as usize),
        device,
    )
}
