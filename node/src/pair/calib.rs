//! A pair's calibration, from flags or from the ROS `camera_calibration` YAML files of the
//! two cameras (what `cameracalibrator` writes and `camera_info_manager` reads). The
//! rectified projection matrix `P` gives the rig the pair is reconstructed in: intrinsics
//! from the left file's `P`, the baseline from the right file's `P[0,3] = -fx * B`, or from
//! `--baseline`.
//!
//! Files that describe raw cameras (a lens distortion, a rectification rotation, or a `K`
//! other than `P`'s left 3x3) make the images raw: [`CalibrationInput::rectifier`] gives the
//! two remap tables that bring them into that rig, as the node does for a driver's
//! `image_raw` (`crate::rectify`), unless `pre_rectified` says the images are rectified
//! already (only `P` is used then). A file with `P` alone (no `camera_matrix`) is a
//! rectified camera.
//!
//! Checks: the calibration's image size is the images' size, the right camera's intrinsics
//! equal the left's (a rectified pair shares them), both baselines agree when both are given,
//! and focal lengths, principal point and baseline lie in the ranges the node accepts from a
//! live camera ([`InputLimits::check_camera`], any image size).

use std::path::{Path, PathBuf};

use renderer::Intrinsics;
use serde::Deserialize;

use super::images::same_size;
use super::PairError;
use crate::error_text::error_chain as chain;
use crate::msg::image::intrinsics_from_camera_info;
use crate::msg::sensor_msgs::CameraInfo;
use crate::rectify::{StereoRectifier, StereoRig};
use crate::service::InputLimits;

/// A rectified rig at the input image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// Intrinsics of both rectified cameras at the input size.
    pub intrinsics: Intrinsics,
    /// Distance between the camera centres, metres (right camera along the left's +x).
    pub baseline: f64,
}

impl Calibration {
    /// `fx * baseline`: disparity in input pixels = this / depth in metres.
    pub fn disparity_per_inverse_depth(&self) -> f64 {
        self.intrinsics.fx as f64 * self.baseline
    }
}

/// Where the calibration comes from, as the command line gives it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CalibrationInput {
    /// Focal length along x, pixels.
    pub fx: Option<f64>,
    /// Focal length along y, pixels (default: `fx`).
    pub fy: Option<f64>,
    /// Principal point x, pixels (default: the image centre).
    pub cx: Option<f64>,
    /// Principal point y, pixels (default: the image centre).
    pub cy: Option<f64>,
    /// Baseline, metres.
    pub baseline: Option<f64>,
    /// The left camera's camera-info YAML.
    pub camera_info: Option<PathBuf>,
    /// The right camera's camera-info YAML.
    pub camera_info_right: Option<PathBuf>,
    /// The images are rectified already: only the files' `P` is used, never their lens.
    pub pre_rectified: bool,
}

/// A matrix in a camera-info YAML (`rows`, `cols`, row-major `data`).
#[derive(Deserialize)]
struct YamlMatrix {
    data: Vec<f64>,
}

/// The fields of a camera-info YAML: size and `P`, and the raw camera's `K`, lens and `R`
/// where the file has them.
#[derive(Deserialize)]
struct CameraInfoYaml {
    image_width: u32,
    image_height: u32,
    camera_matrix: Option<YamlMatrix>,
    distortion_model: Option<String>,
    distortion_coefficients: Option<YamlMatrix>,
    rectification_matrix: Option<YamlMatrix>,
    projection_matrix: YamlMatrix,
}

/// `matrix`'s values as `N` numbers, or a clear error naming the file and the field.
fn values<const N: usize>(
    path: &Path,
    field: &str,
    matrix: YamlMatrix,
) -> Result<[f64; N], PairError> {
    matrix.data.try_into().map_err(|d: Vec<f64>| {
        PairError::InconsistentCalibration(format!(
            "{}: {field} has {} values, {N} expected",
            path.display(),
            d.len()
        ))
    })
}

/// Reads a camera-info YAML into a `CameraInfo` message: size, `P`, and `K`, `D` and `R`
/// (without `camera_matrix`: `P`'s left 3x3; without the others: no lens, `R` the identity).
pub fn read_camera_info(path: &Path) -> Result<CameraInfo, PairError> {
    let text = std::fs::read_to_string(path).map_err(|source| PairError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let yaml: CameraInfoYaml =
        serde_yaml::from_str(&text).map_err(|source| PairError::CameraInfoYaml {
            path: path.to_path_buf(),
            source,
        })?;
    let p: [f64; 12] = values(path, "projection_matrix", yaml.projection_matrix)?;
    let k = match yaml.camera_matrix {
        Some(m) => values(path, "camera_matrix", m)?,
        None => [p[0], p[1], p[2], p[4], p[5], p[6], p[8], p[9], p[10]],
    };
    let r = match yaml.rectification_matrix {
        Some(m) => values(path, "rectification_matrix", m)?,
        None => [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    };
    Ok(CameraInfo {
        width: yaml.image_width,
        height: yaml.image_height,
        distortion_model: yaml.distortion_model.unwrap_or_else(|| "plumb_bob".into()),
        d: yaml
            .distortion_coefficients
            .map(|m| m.data)
            .unwrap_or_default(),
        k,
        r,
        p,
        ..CameraInfo::default()
    })
}

/// Intrinsics and baseline (0 for a left camera) of a camera-info file.
fn from_file(path: &Path) -> Result<(Intrinsics, f64), PairError> {
    intrinsics_from_camera_info(&read_camera_info(path)?)
        .map_err(|e| PairError::InconsistentCalibration(format!("{}: {e}", path.display())))
}

/// Whether two intrinsics are the same within 0.01 px (YAML files round their numbers).
fn same_intrinsics(a: &Intrinsics, b: &Intrinsics) -> bool {
    let close = |x: f32, y: f32| (x - y).abs() <= 1e-2 + 1e-5 * x.abs().max(y.abs());
    (a.width, a.height) == (b.width, b.height)
        && close(a.fx, b.fx)
        && close(a.fy, b.fy)
        && close(a.cx, b.cx)
        && close(a.cy, b.cy)
}

impl CalibrationInput {
    /// The calibration for images of `size`, checked (see the module documentation).
    pub fn resolve(&self, size: (u32, u32)) -> Result<Calibration, PairError> {
        let flags = [self.fx, self.fy, self.cx, self.cy];
        let (intrinsics, file_baseline) = match &self.camera_info {
            Some(_) if flags.iter().any(Option::is_some) => {
                return Err(PairError::InconsistentCalibration(
                    "give intrinsics either as flags or as --camera-info, not both".into(),
                ))
            }
            Some(left) => self.files_rig(left)?,
            None => {
                if self.camera_info_right.is_some() {
                    return Err(PairError::MissingCalibration(
                        "--camera-info-right needs the left camera's --camera-info".into(),
                    ));
                }
                let fx = self.fx.ok_or_else(|| {
                    PairError::MissingCalibration(
                        "no focal length: give --fx (and --fy, --cx, --cy) or --camera-info".into(),
                    )
                })?;
                let centre = |n: u32| (n as f64 - 1.0) * 0.5;
                let k = Intrinsics {
                    fx: fx as f32,
                    fy: self.fy.unwrap_or(fx) as f32,
                    cx: self.cx.unwrap_or(centre(size.0)) as f32,
                    cy: self.cy.unwrap_or(centre(size.1)) as f32,
                    width: size.0,
                    height: size.1,
                };
                (k, None)
            }
        };
        let baseline = match (self.baseline, file_baseline) {
            (Some(a), Some(b)) if (a - b).abs() > 1e-3 * a.abs().max(b.abs()) => {
                return Err(PairError::InconsistentCalibration(format!(
                    "--baseline {a} m but the right camera's P gives {b} m"
                )))
            }
            (Some(b), _) | (None, Some(b)) => b,
            (None, None) => {
                return Err(PairError::MissingCalibration(
                    "no baseline: give --baseline or the right camera's --camera-info-right".into(),
                ))
            }
        };
        same_size(
            "calibration and images",
            (intrinsics.width, intrinsics.height),
            size,
        )?;
        let limits = InputLimits {
            max_width: u32::MAX,
            max_height: u32::MAX,
            max_pixels: u64::MAX,
            ..InputLimits::default()
        };
        limits
            .check_camera(&intrinsics, Some(baseline))
            .map_err(|e| PairError::InconsistentCalibration(e.to_string()))?;
        Ok(Calibration {
            intrinsics,
            baseline,
        })
    }

    /// The remap tables that rectify the images, when the files describe raw cameras (see
    /// the module documentation); `None` for rectified cameras, flags, or `pre_rectified`.
    /// Raw cameras need both files: the rig is checked as the node checks a driver's two
    /// camera infos ([`StereoRig::from_camera_infos`]).
    pub fn rectifier(&self) -> Result<Option<StereoRectifier>, PairError> {
        let Some(left) = self.camera_info.as_deref().filter(|_| !self.pre_rectified) else {
            return Ok(None);
        };
        let left_info = read_camera_info(left)?;
        let Some(right) = &self.camera_info_right else {
            let model = crate::rectify::CameraModel::from_camera_info(&left_info).map_err(|e| {
                PairError::InconsistentCalibration(format!("{}: {}", left.display(), chain(&e)))
            })?;
            return match model.is_rectified() {
                true => Ok(None),
                false => Err(PairError::MissingCalibration(format!(
                    "{} describes a raw camera (a lens or a rectification): rectifying the pair \
                     needs the right camera's --camera-info-right too (or --pre-rectified for \
                     images rectified already)",
                    left.display()
                ))),
            };
        };
        let rig = StereoRig::from_camera_infos(&left_info, &read_camera_info(right)?)
            .map_err(|e| PairError::InconsistentCalibration(chain(&e)))?;
        let rectified = rig.left.is_rectified() && rig.right.is_rectified();
        Ok((!rectified).then(|| StereoRectifier::new(rig)))
    }

    /// Intrinsics from the left file and the baseline from the right file, if given.
    fn files_rig(&self, left: &Path) -> Result<(Intrinsics, Option<f64>), PairError> {
        let (k, _) = from_file(left)?;
        let Some(right) = &self.camera_info_right else {
            return Ok((k, None));
        };
        let (k_right, baseline) = from_file(right)?;
        if !same_intrinsics(&k, &k_right) {
            return Err(PairError::InconsistentCalibration(format!(
                "the rectified intrinsics differ: left {k:?}, right {k_right:?}"
            )));
        }
        Ok((k, Some(baseline)))
    }
}
