//! One KITTI-360 sequence opened for reading: its calibration, rig, posed frames, and
//! loaders for stereo frames, velodyne scans and LiDAR depth maps, optionally at a lower
//! resolution than the 1408x376 of the files.

use std::path::{Path, PathBuf};

use glam::{DAffine3, DVec3};

use super::calibration::Calibration;
use super::error::Kitti360Error;
use super::exact_depth::read_depth_png;
use super::images::read_png_rgb8;
use super::layout;
use super::lidar_depth::project_depth;
use super::poses::{read_pose_file, FramePose, PoseFormat, SkippedFrame};
use super::resample::resample_area;
use super::timestamps::read_timestamps;
use super::velodyne::read_scan;
use crate::frame::{DepthMap, Rgb8Image, Side, StereoFrame, StereoRig};

/// A frame's two images as interleaved 8-bit RGB, with the left camera's pose.
#[derive(Clone, Debug)]
pub struct Rgb8Frame {
    /// Left image.
    pub left: Rgb8Image,
    /// Right image, the left's size.
    pub right: Rgb8Image,
    /// Left camera to world.
    pub left_to_world: DAffine3,
}

/// A KITTI-360 sequence (`2013_05_28_drive_0000_sync`) under a dataset root.
#[derive(Clone, Debug)]
pub struct Sequence {
    root: PathBuf,
    name: String,
    calibration: Calibration,
    native: StereoRig,
    rig: StereoRig,
    pose_file: PathBuf,
    frames: Vec<FramePose>,
    skipped: Vec<SkippedFrame>,
}

impl Sequence {
    /// Opens `seq` under `root`: reads the calibration, then the poses from
    /// `cam0_to_world.txt` if present, else from `poses.txt` turned into rectified camera 0
    /// to world by `pose * cam_to_pose_00 * inverse(R_rect_00)` (devkit `helpers/project.py`).
    /// Frames with a non-finite or non-rigid pose are skipped and listed in
    /// [`Sequence::skipped`]. Timestamps come from `image_00/timestamps.txt` when present.
    pub fn open(root: &Path, seq: &str) -> Result<Self, Kitti360Error> {
        if !layout::valid_sequence_name(seq) {
            return Err(Kitti360Error::BadSequenceName {
                root: root.into(),
                name: seq.into(),
            });
        }
        let calibration = Calibration::read(root)?;
        let rig = calibration.rig_under(root)?;
        let cam0 = layout::cam0_to_world(root, seq);
        let (pose_file, poses, skipped) = if cam0.is_file() {
            let (poses, skipped) = read_pose_file(&cam0, PoseFormat::FourByFour)?;
            (cam0, poses, skipped)
        } else {
            let path = layout::poses(root, seq);
            let (poses, skipped) = read_pose_file(&path, PoseFormat::ThreeByFour)?;
            let rect_to_pose = calibration.rect_to_pose();
            let poses = poses
                .into_iter()
                .map(|(i, p)| (i, p * rect_to_pose))
                .collect();
            (path, poses, skipped)
        };
        let stamps = read_timestamps(&layout::image_timestamps(root, seq, Side::Left))?;
        let frames = poses
            .into_iter()
            .map(|(index, left_to_world)| FramePose {
                index,
                left_to_world,
                timestamp_ns: stamps.as_ref().and_then(|s| s.get(index as usize).copied()),
            })
            .collect();
        Ok(Self {
            root: root.into(),
            name: seq.into(),
            calibration,
            native: rig,
            rig,
            pose_file,
            frames,
            skipped,
        })
    }

    /// The sequence directory names under `root/data_2d_raw`, sorted.
    pub fn list(root: &Path) -> Result<Vec<String>, Kitti360Error> {
        let dir = layout::images_root(root);
        let entries = std::fs::read_dir(&dir).map_err(|e| Kitti360Error::io(&dir, e))?;
        let mut names = Vec::new();
        for entry in entries {
            let entry = entry.map_err(|e| Kitti360Error::io(&dir, e))?;
            let is_dir = entry
                .file_type()
                .map_err(|e| Kitti360Error::io(entry.path(), e))?
                .is_dir();
            if let (true, Some(name)) = (is_dir, entry.file_name().to_str()) {
                names.push(name.to_string());
            }
        }
        names.sort();
        Ok(names)
    }

    /// Frames load at `width` x `height` instead of the calibration's size: images are
    /// area-averaged ([`super::resample`]), the rig's intrinsics scaled with
    /// [`renderer::Intrinsics::scaled`] (baseline unchanged), and LiDAR depth is projected at
    /// that size. Zero sizes are raised to 1.
    pub fn with_resolution(mut self, width: u32, height: u32) -> Self {
        self.rig.intrinsics = self.native.intrinsics.scaled(width.max(1), height.max(1));
        self
    }

    /// The sequence name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The rectified rig at the resolution frames load at.
    pub fn rig(&self) -> StereoRig {
        self.rig
    }

    /// The calibration as read (at the files' resolution).
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// The posed frames, sorted by index.
    pub fn frames(&self) -> &[FramePose] {
        &self.frames
    }

    /// The frames the pose file lists but whose pose was unusable.
    pub fn skipped(&self) -> &[SkippedFrame] {
        &self.skipped
    }

    /// The pose file the frames came from (`cam0_to_world.txt` or `poses.txt`).
    pub fn pose_file(&self) -> &Path {
        &self.pose_file
    }

    /// The posed frame `index`, or [`Kitti360Error::UnknownFrame`].
    pub fn frame(&self, index: u32) -> Result<&FramePose, Kitti360Error> {
        self.frames
            .binary_search_by_key(&index, |f| f.index)
            .map(|i| &self.frames[i])
            .map_err(|_| Kitti360Error::UnknownFrame {
                index,
                poses: self.pose_file.clone(),
            })
    }

    /// Loads the rectified stereo pair of frame `index` with its pose. Errors: unknown
    /// frame, missing or corrupt PNG, right size differing from the left, left size
    /// differing from `S_rect_00`.
    pub fn load_frame(&self, index: u32) -> Result<StereoFrame, Kitti360Error> {
        let (left_to_world, left, right) = self.read_pair(index)?;
        let k = self.rig.intrinsics;
        let image = |png: Rgb8Image| resample_area(&png.to_rgb(), k.width, k.height);
        Ok(StereoFrame {
            index,
            left: image(left),
            right: image(right),
            left_to_world,
        })
    }

    /// [`Self::load_frame`] as interleaved 8-bit RGB at the rig's size, for publishing:
    /// the PNGs' own bytes when they have that size (no round trip through floats), else
    /// the resampled images rounded back to bytes. Same errors.
    pub fn load_frame_rgb8(&self, index: u32) -> Result<Rgb8Frame, Kitti360Error> {
        let (left_to_world, left, right) = self.read_pair(index)?;
        let k = self.rig.intrinsics;
        let bytes = |png: Rgb8Image| match (png.width, png.height) == (k.width, k.height) {
            true => png,
            false => Rgb8Image {
                width: k.width,
                height: k.height,
                data: resample_area(&png.to_rgb(), k.width, k.height).to_rgb8(),
            },
        };
        Ok(Rgb8Frame {
            left: bytes(left),
            right: bytes(right),
            left_to_world,
        })
    }

    /// Frame `index`'s two PNGs as decoded, sizes checked, with its pose.
    fn read_pair(&self, index: u32) -> Result<(DAffine3, Rgb8Image, Rgb8Image), Kitti360Error> {
        let pose = self.frame(index)?;
        let left_path = layout::image(&self.root, &self.name, Side::Left, index);
        let right_path = layout::image(&self.root, &self.name, Side::Right, index);
        let left = read_png_rgb8(&left_path)?;
        let right = read_png_rgb8(&right_path)?;
        let size = |img: &Rgb8Image| (img.width, img.height);
        if size(&left) != self.calibration.image_size {
            return Err(Kitti360Error::SizeMismatch {
                path: left_path,
                expected: self.calibration.image_size,
                found: size(&left),
            });
        }
        if size(&right) != size(&left) {
            return Err(Kitti360Error::SizeMismatch {
                path: right_path,
                expected: size(&left),
                found: size(&right),
            });
        }
        Ok((pose.left_to_world, left, right))
    }

    /// The velodyne scan of frame `index` (velodyne frame, x y z reflectance).
    pub fn load_lidar(&self, index: u32) -> Result<Vec<[f32; 4]>, Kitti360Error> {
        self.frame(index)?;
        read_scan(&layout::velodyne(&self.root, &self.name, index))
    }

    /// Exact depth of frame `index` in one camera at the rig's resolution (nearest stored
    /// pixel where the sequence is read at another size), where the drive was generated with
    /// it; `None` for real data, which has none (no file). 0 where unknown.
    pub fn exact_depth(&self, index: u32, side: Side) -> Result<Option<DepthMap>, Kitti360Error> {
        self.frame(index)?;
        let k = &self.rig.intrinsics;
        match read_depth_png(&layout::exact_depth(&self.root, &self.name, side, index)) {
            Ok(depth) => Ok(Some(depth.nearest(k.width, k.height))),
            Err(Kitti360Error::MissingFile { .. }) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Sparse depth of frame `index` in one rectified camera at the rig's resolution: the
    /// scan brought into rectified camera 0 by `R_rect_00 * inverse(cam_to_velo)` (devkit
    /// `projectVeloToImage`), for the right camera then moved by the baseline (what
    /// `P_rect_01` encodes, and where [`StereoRig::camera_to_world`] puts it), projected with
    /// the nearest point kept per pixel. The scan is not motion-compensated.
    pub fn lidar_depth(&self, index: u32, side: Side) -> Result<DepthMap, Kitti360Error> {
        let points = self.load_lidar(index)?;
        let to_left = self.calibration.velo_to_rect();
        let to_camera = match side {
            Side::Left => to_left,
            Side::Right => {
                DAffine3::from_translation(DVec3::new(-self.rig.baseline, 0.0, 0.0)) * to_left
            }
        };
        Ok(project_depth(&points, &to_camera, &self.rig.intrinsics))
    }
}
