//! The one error type of the KITTI-360 reader and writer: every variant names the file it
//! concerns (and the line, for text formats), so a user can find and fix the bad input.

use std::path::PathBuf;

/// Why reading or writing a KITTI-360 layout failed.
#[derive(Debug, thiserror::Error)]
pub enum Kitti360Error {
    /// The file system refused an operation on `path`.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory involved.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// A text file has a line that does not have the expected shape.
    #[error("{}:{line}: {reason}", path.display())]
    Parse {
        /// The text file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the line.
        reason: String,
    },
    /// A keyed text file (`perspective.txt`, `calib_cam_to_pose.txt`) lacks a needed key.
    #[error("{}: missing key `{key}`", path.display())]
    MissingKey {
        /// The text file.
        path: PathBuf,
        /// The key, without its colon.
        key: String,
    },
    /// A file the layout needs is not there.
    #[error("{}: missing file", path.display())]
    MissingFile {
        /// Where it should be.
        path: PathBuf,
    },
    /// A PNG could not be decoded or encoded.
    #[error("{}: bad PNG: {reason}", path.display())]
    Png {
        /// The image file.
        path: PathBuf,
        /// The decoder's or encoder's message.
        reason: String,
    },
    /// An image does not have the size it must have (the left image's, or `S_rect_00`).
    #[error("{}: image is {}x{}, expected {}x{}", path.display(), found.0, found.1, expected.0, expected.1)]
    SizeMismatch {
        /// The offending image (or, when writing, the file it was meant for).
        path: PathBuf,
        /// The size it must have, width x height.
        expected: (u32, u32),
        /// Its size.
        found: (u32, u32),
    },
    /// A velodyne scan holds no point.
    #[error("{}: empty velodyne scan", path.display())]
    EmptyLidar {
        /// The `.bin` file.
        path: PathBuf,
    },
    /// A velodyne scan's length is not a whole number of 16-byte points.
    #[error("{}: {len} bytes is not a multiple of 16 (x y z reflectance as float32)", path.display())]
    BadLidarLength {
        /// The `.bin` file.
        path: PathBuf,
        /// Its length in bytes.
        len: u64,
    },
    /// The calibration does not describe an exactly rectified stereo pair.
    #[error("{}: not a rectified stereo calibration: {reason}", path.display())]
    NonRectified {
        /// The calibration file the values come from (`calibration/perspective.txt`).
        path: PathBuf,
        /// Which condition fails.
        reason: String,
    },
    /// A frame index that the pose file does not list (KITTI-360 has no frame without a pose).
    #[error("{}: frame {index} has no pose", poses.display())]
    UnknownFrame {
        /// The frame index asked for.
        index: u32,
        /// The pose file the sequence was opened from.
        poses: PathBuf,
    },
    /// The writer was given a frame whose pose is not finite.
    #[error("{}: frame {index} has a non-finite pose", path.display())]
    NonFinitePose {
        /// The pose file the frame was meant for.
        path: PathBuf,
        /// The frame index.
        index: u32,
    },
    /// The writer was given the same frame index twice.
    #[error("{}: frame {index} was written twice", path.display())]
    DuplicateFrame {
        /// The file the second write was meant for.
        path: PathBuf,
        /// The frame index.
        index: u32,
    },
    /// A calibration file already under the root differs from the one being written.
    #[error("{}: differs from the calibration being written", path.display())]
    CalibrationConflict {
        /// The existing file.
        path: PathBuf,
    },
    /// A sequence name that is empty or not a single directory name.
    #[error("{}: `{name}` is not a sequence directory name", root.display())]
    BadSequenceName {
        /// The dataset root.
        root: PathBuf,
        /// The name given.
        name: String,
    },
}

impl Kitti360Error {
    /// An I/O error on `path`, turning "not found" into [`Kitti360Error::MissingFile`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        let path = path.into();
        match source.kind() {
            std::io::ErrorKind::NotFound => Self::MissingFile { path },
            _ => Self::Io { path, source },
        }
    }

    /// A parse error at `line` (1-based) of `path`.
    pub fn parse(path: impl Into<PathBuf>, line: usize, reason: impl Into<String>) -> Self {
        Self::Parse {
            path: path.into(),
            line,
            reason: reason.into(),
        }
    }
}
