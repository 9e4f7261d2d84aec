//! One rectified stereo pair from image files, the way a user with their own rig has it:
//! loaded ([`images`]), calibrated from flags or ROS `camera_calibration` YAML ([`calib`]),
//! checked for rectification ([`rectified`]), reconstructed at a working size by any
//! reconstructor and rendered back at the input size ([`run`]), scored against a
//! ground-truth disparity ([`truth`]) or by photometric consistency ([`photometric`]), and
//! written out ([`outputs`]). `stereosplat reconstruct` is this module behind flags.

pub mod calib;
pub mod images;
pub mod outputs;
pub mod photometric;
pub mod rectified;
pub mod run;
pub mod truth;

use std::path::PathBuf;

pub use calib::Calibration;
pub use run::{reconstruct_pair, DepthRule, PairOptions, PairReconstruction};

/// Why a stereo pair could not be reconstructed or scored.
#[derive(Debug, thiserror::Error)]
pub enum PairError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// An image file does not decode.
    #[error("{path} is not a readable image")]
    Decode {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        #[source]
        source: image::ImageError,
    },
    /// The two images (or an image and its calibration or ground truth) differ in size.
    #[error("{what}: {a_w}x{a_h} against {b_w}x{b_h}")]
    SizeMismatch {
        /// Which sizes disagree.
        what: String,
        /// First width.
        a_w: u32,
        /// First height.
        a_h: u32,
        /// Second width.
        b_w: u32,
        /// Second height.
        b_h: u32,
    },
    /// No calibration, or part of it missing.
    #[error("missing calibration: {0}")]
    MissingCalibration(String),
    /// A calibration that no real rectified rig has, or two files that disagree.
    #[error("inconsistent calibration: {0}")]
    InconsistentCalibration(String),
    /// A camera-info YAML file that does not parse.
    #[error("{path} is not a ROS camera_calibration YAML file")]
    CameraInfoYaml {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        #[source]
        source: serde_yaml::Error,
    },
    /// The pair does not look rectified: matched patches sit on different rows.
    #[error(
        "the pair does not look rectified: patches match {median_px:.1} px (median |vertical \
         disparity| over {patches} textured patches, input pixels) above or below their row; \
         the limit is {limit_px} px"
    )]
    NotRectified {
        /// Median absolute vertical disparity, input pixels.
        median_px: f32,
        /// Patches that matched.
        patches: usize,
        /// The limit it exceeds.
        limit_px: f32,
    },
    /// The reconstructor failed.
    #[error("reconstruction failed")]
    Reconstruct(#[source] model::reconstruct::ReconstructError),
    /// The Gaussians could not be rendered or written.
    #[error("writing the outputs failed")]
    Picture(#[source] renderer::picture::PictureError),
    /// The PLY could not be written.
    #[error("writing the PLY failed")]
    Ply(#[source] renderer::ply::PlyError),
    /// The Gaussians could not be viewed for rendering.
    #[error("the reconstruction's Gaussians are malformed: {0}")]
    Gaussians(String),
}
