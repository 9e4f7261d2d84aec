//! Writing a sequence in the KITTI-360 layout, so synthetic data (and anything else) can be
//! read back by [`super::Sequence`] or by the official devkit. The output is
//! byte-deterministic: fixed number format ([`super::text::sci`]), frames in index order.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::DAffine3;

use super::calibration::Calibration;
use super::error::Kitti360Error;
use super::exact_depth::write_depth_png;
use super::images::write_png;
use super::layout;
use super::poses::{write_pose_file, PoseFormat};
use super::timestamps::{fill_timestamps, write_timestamps};
use super::velodyne::write_scan;
use crate::frame::{DepthMap, RgbImage, Side, StereoFrame};

/// Writes one sequence: images and scans as they come, poses and timestamps at
/// [`SequenceWriter::finish`]. Existing files of the same names are overwritten.
#[derive(Debug)]
pub struct SequenceWriter {
    root: PathBuf,
    name: String,
    calibration: Calibration,
    poses: BTreeMap<u32, DAffine3>,
    image_stamps: BTreeMap<u32, i64>,
    lidar_stamps: BTreeMap<u32, i64>,
}

impl SequenceWriter {
    /// Starts sequence `seq` under `root` and writes the calibration files. Calibration
    /// files already there (another sequence of the same root) are kept when byte-identical
    /// to what this calibration writes, and are an error otherwise. The calibration must be
    /// rectified-consistent ([`Calibration::rig`]).
    pub fn create(
        root: &Path,
        seq: &str,
        calibration: &Calibration,
    ) -> Result<Self, Kitti360Error> {
        if !layout::valid_sequence_name(seq) {
            return Err(Kitti360Error::BadSequenceName {
                root: root.into(),
                name: seq.into(),
            });
        }
        calibration.rig_under(root)?;
        for (path, text) in calibration.files(root) {
            match std::fs::read(&path) {
                Ok(existing) if existing == text.as_bytes() => {}
                Ok(_) => return Err(Kitti360Error::CalibrationConflict { path }),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    super::text::write_text(&path, &text)?
                }
                Err(e) => return Err(Kitti360Error::io(path, e)),
            }
        }
        Ok(Self {
            root: root.into(),
            name: seq.into(),
            calibration: calibration.clone(),
            poses: BTreeMap::new(),
            image_stamps: BTreeMap::new(),
            lidar_stamps: BTreeMap::new(),
        })
    }

    /// Writes the two PNGs of `frame` and records its pose and capture time (nanoseconds
    /// since the Unix epoch). Errors: a frame index written before, a non-finite pose, a
    /// left image not of the calibration's size, a right image not of the left's size.
    pub fn write_frame(
        &mut self,
        frame: &StereoFrame,
        timestamp_ns: i64,
    ) -> Result<(), Kitti360Error> {
        let index = frame.index;
        let left_path = layout::image(&self.root, &self.name, Side::Left, index);
        let right_path = layout::image(&self.root, &self.name, Side::Right, index);
        if self.poses.contains_key(&index) {
            return Err(Kitti360Error::DuplicateFrame {
                path: left_path,
                index,
            });
        }
        if !frame.left_to_world.is_finite() {
            return Err(Kitti360Error::NonFinitePose {
                path: layout::cam0_to_world(&self.root, &self.name),
                index,
            });
        }
        let size = |img: &RgbImage| (img.width, img.height);
        if size(&frame.left) != self.calibration.image_size {
            return Err(Kitti360Error::SizeMismatch {
                path: left_path,
                expected: self.calibration.image_size,
                found: size(&frame.left),
            });
        }
        if size(&frame.right) != size(&frame.left) {
            return Err(Kitti360Error::SizeMismatch {
                path: right_path,
                expected: size(&frame.left),
                found: size(&frame.right),
            });
        }
        write_png(&left_path, &frame.left)?;
        write_png(&right_path, &frame.right)?;
        self.poses.insert(index, frame.left_to_world);
        self.image_stamps.insert(index, timestamp_ns);
        Ok(())
    }

    /// Writes the velodyne scan of frame `index` (velodyne frame, x y z reflectance) and
    /// records its time. Errors: an index written before, an empty scan.
    pub fn write_lidar(
        &mut self,
        index: u32,
        points: &[[f32; 4]],
        timestamp_ns: i64,
    ) -> Result<(), Kitti360Error> {
        let path = layout::velodyne(&self.root, &self.name, index);
        if self.lidar_stamps.contains_key(&index) {
            return Err(Kitti360Error::DuplicateFrame { path, index });
        }
        write_scan(&path, points)?;
        self.lidar_stamps.insert(index, timestamp_ns);
        Ok(())
    }

    /// Writes the exact depth of one camera of frame `index` (generated drives only; see
    /// [`super::exact_depth`]). Errors: a map not of the calibration's size.
    pub fn write_exact_depth(
        &self,
        index: u32,
        side: Side,
        depth: &DepthMap,
    ) -> Result<(), Kitti360Error> {
        let path = layout::exact_depth(&self.root, &self.name, side, index);
        if (depth.width, depth.height) != self.calibration.image_size {
            return Err(Kitti360Error::SizeMismatch {
                path,
                expected: self.calibration.image_size,
                found: (depth.width, depth.height),
            });
        }
        write_depth_png(&path, depth)
    }

    /// Writes the pose files and timestamps: `cam0_to_world.txt` with the frames' poses,
    /// `poses.txt` with `cam0_to_world * inverse(cam_to_pose_00 * inverse(R_rect_00))` so
    /// the devkit derives the same camera poses from it, and `timestamps.txt` for both
    /// cameras (and the velodyne, if scans were written), line k for frame k; frames not
    /// written get times interpolated from their neighbours.
    pub fn finish(self) -> Result<(), Kitti360Error> {
        let cam0: Vec<(u32, DAffine3)> = self.poses.iter().map(|(&i, &p)| (i, p)).collect();
        let pose_from_cam = self.calibration.rect_to_pose().inverse();
        let imu: Vec<(u32, DAffine3)> = cam0.iter().map(|&(i, p)| (i, p * pose_from_cam)).collect();
        let (root, seq) = (&self.root, self.name.as_str());
        write_pose_file(
            &layout::cam0_to_world(root, seq),
            PoseFormat::FourByFour,
            &cam0,
        )?;
        write_pose_file(&layout::poses(root, seq), PoseFormat::ThreeByFour, &imu)?;
        let stamps = fill_timestamps(&self.image_stamps);
        for side in [Side::Left, Side::Right] {
            write_timestamps(&layout::image_timestamps(root, seq, side), &stamps)?;
        }
        if !self.lidar_stamps.is_empty() {
            let stamps = fill_timestamps(&self.lidar_stamps);
            write_timestamps(&layout::velodyne_timestamps(root, seq), &stamps)?;
        }
        Ok(())
    }
}
