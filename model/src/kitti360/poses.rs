//! The pose files of `data_poses/<seq>/`: `poses.txt` (frame index and 12 numbers, the 3x4
//! row-major GPS/IMU-to-world) and `cam0_to_world.txt` (frame index and 16 numbers, the 4x4
//! row-major rectified-camera-0-to-world), as the devkit's `helpers/project.py` and the
//! dataset's documentation describe them. Only frames listed here exist for KITTI-360.

use std::path::Path;

use glam::{DAffine3, DMat3};

use super::error::Kitti360Error;
use super::text::{
    affine_from_rows, affine_rows, parse_all, parse_index, read_text, sci_join, write_text,
};

/// How far from orthonormal (max entry of `R^T R - I`) a pose's rotation may be: the
/// published files print rotations with 6 to 10 digits.
const RIGID_TOL: f64 = 1e-3;

/// One posed frame of a sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FramePose {
    /// The frame number (the `%010d` of the file names).
    pub index: u32,
    /// Rectified left camera (`image_00`) to world, f64.
    pub left_to_world: DAffine3,
    /// Capture time of the left image, nanoseconds since the Unix epoch (UTC), when
    /// `image_00/timestamps.txt` has it.
    pub timestamp_ns: Option<i64>,
}

/// A frame listed in the pose file but left out, and why (a non-finite or non-rigid pose).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SkippedFrame {
    /// The frame number.
    pub index: u32,
    /// What is wrong with its pose.
    pub reason: String,
}

/// Poses by frame index, as a pose file lists them.
pub type IndexedPoses = Vec<(u32, DAffine3)>;

/// Which pose file: its matrix shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoseFormat {
    /// `poses.txt`: index + 3x4.
    ThreeByFour,
    /// `cam0_to_world.txt`: index + 4x4.
    FourByFour,
}

impl PoseFormat {
    fn numbers(self) -> usize {
        match self {
            Self::ThreeByFour => 12,
            Self::FourByFour => 16,
        }
    }
}

/// Why a finite 3x4 pose is not a rigid transform, if it is not.
fn rigid_problem(pose: &DAffine3) -> Option<String> {
    let r = pose.matrix3;
    let err = (r.transpose() * r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    match err <= RIGID_TOL && r.determinant() > 0.0 {
        true => None,
        false => Some(format!(
            "rotation is not a rotation (orthonormality error {err:.3e})"
        )),
    }
}

/// The poses of a pose file, sorted by frame, and the frames skipped for a bad pose. A line
/// of the wrong length, a bad number or a repeated frame is a parse error naming the line.
pub fn read_pose_file(
    path: &Path,
    format: PoseFormat,
) -> Result<(IndexedPoses, Vec<SkippedFrame>), Kitti360Error> {
    let text = read_text(path)?;
    let mut poses = IndexedPoses::new();
    let mut skipped = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for (i, line) in text.lines().enumerate() {
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.is_empty() {
            continue;
        }
        let n = format.numbers();
        if tokens.len() != n + 1 {
            return Err(Kitti360Error::parse(
                path,
                i + 1,
                format!(
                    "expected a frame index and {n} numbers, found {} fields",
                    tokens.len()
                ),
            ));
        }
        let index = parse_index(path, i + 1, tokens[0])?;
        if !seen.insert(index) {
            return Err(Kitti360Error::parse(
                path,
                i + 1,
                format!("frame {index} listed twice"),
            ));
        }
        let values = parse_all(path, i + 1, &tokens[1..])?;
        let problem = if values.iter().any(|v| !v.is_finite()) {
            Some("pose holds a non-finite number".to_string())
        } else if format == PoseFormat::FourByFour && values[12..] != [0.0, 0.0, 0.0, 1.0] {
            Some("last row is not 0 0 0 1".to_string())
        } else {
            rigid_problem(&affine_from_rows(&values[..12]))
        };
        match problem {
            Some(reason) => skipped.push(SkippedFrame { index, reason }),
            None => poses.push((index, affine_from_rows(&values[..12]))),
        }
    }
    poses.sort_by_key(|(index, _)| *index);
    Ok((poses, skipped))
}

/// Writes a pose file, one line per pose in the given order: the index, then the numbers in
/// the [`super::text::sci`] format.
pub fn write_pose_file(
    path: &Path,
    format: PoseFormat,
    poses: &[(u32, DAffine3)],
) -> Result<(), Kitti360Error> {
    let mut text = String::new();
    for (index, pose) in poses {
        let mut values = affine_rows(pose).to_vec();
        if format == PoseFormat::FourByFour {
            values.extend([0.0, 0.0, 0.0, 1.0]);
        }
        text += &format!("{index} {}\n", sci_join(&values));
    }
    write_text(path, &text)
}
