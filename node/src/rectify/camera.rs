//! One camera's calibration read from a `sensor_msgs/CameraInfo` and checked: the raw
//! image's intrinsics K and lens model D, the rectification rotation R and the rectified
//! projection P, at the size of the images the camera publishes (binning applied as
//! ROS's `image_geometry` applies it). What [`super::RemapTable`] is built from.
//!
//! Choices, where ROS or OpenCV leave room:
//! - `plumb_bob` takes 5 coefficients, or 4 (k3 = 0, as OpenCV reads 4); 8 are refused as
//!   a mislabelled `rational_polynomial`. `rational_polynomial` takes 8, `equidistant` 4.
//!   An empty D, under any model name or none, is a pinhole; so is an empty model name with
//!   an all-zero D. Other model names are refused.
//! - K must be `[fx 0 cx; 0 fy cy; 0 0 1]` (no skew: OpenCV's rectification ignores it) and
//!   P `[fx' 0 cx' Tx; 0 fy' cy' Ty; 0 0 1 0]`, focal lengths positive; R a rotation within
//!   [`ROTATION_TOLERANCE`].
//! - Binning divides the focal lengths, principal points and P's translation, and the image
//!   size, by the binning factor (`image_geometry`'s convention, no half-pixel shift). A
//!   region of interest other than the full image (or all zero) is refused.
//! - Already rectified ([`CameraModel::is_rectified`]): D all zero, R the identity within
//!   1e-9 and P's left 3x3 equal to K within 1e-6 px. All three, since a zero D with a P
//!   other than K still moves pixels (image_proc would remap it).

use glam::{DMat3, DVec2, DVec3};
use thiserror::Error;

use super::distortion::Distortion;
use crate::msg::sensor_msgs::{CameraInfo, RegionOfInterest};

/// The largest image side a calibration may declare (its table is 8 bytes a pixel).
pub const MAX_SIDE: u32 = 16384;
/// The most pixels a calibration may declare (8K UHD; a 265 MB table).
pub const MAX_PIXELS: u64 = 7680 * 4320;
/// How far `RᵀR` may be from the identity, and `det R` from 1, for R to count as a
/// rotation: YAML files print R with 5 to 8 decimals.
pub const ROTATION_TOLERANCE: f64 = 1e-4;
/// How far the structural zeros and ones of K and P may be from 0 and 1.
const FORM_TOLERANCE: f64 = 1e-9;

/// Focal lengths and principal point of a pinhole camera, in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pinhole {
    /// Focal length along x.
    pub fx: f64,
    /// Focal length along y.
    pub fy: f64,
    /// Principal point x.
    pub cx: f64,
    /// Principal point y.
    pub cy: f64,
}

impl Pinhole {
    /// `[fx 0 cx; 0 fy cy; 0 0 1]`.
    pub fn matrix(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::new(self.fx, 0.0, 0.0),
            DVec3::new(0.0, self.fy, 0.0),
            DVec3::new(self.cx, self.cy, 1.0),
        )
    }

    /// Pixel coordinates of normalised coordinates `n`.
    pub fn to_pixel(&self, n: DVec2) -> DVec2 {
        DVec2::new(self.fx * n.x + self.cx, self.fy * n.y + self.cy)
    }

    /// Normalised coordinates of pixel coordinates `px`.
    pub fn to_normalised(&self, px: DVec2) -> DVec2 {
        DVec2::new((px.x - self.cx) / self.fx, (px.y - self.cy) / self.fy)
    }
}

/// A checked calibration of one camera. `PartialEq` compares every parameter exactly: the
/// caller rebuilds its table only when a new `CameraInfo` gives a different model.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraModel {
    width: u32,
    height: u32,
    k: Pinhole,
    distortion: Distortion,
    r: DMat3,
    p: Pinhole,
    tx: f64,
    ty: f64,
}

/// Why a `CameraInfo` gives no camera model; each names the field and the value.
#[derive(Debug, Error, PartialEq)]
pub enum CalibrationError {
    /// A number is NaN or infinite.
    #[error("camera_info.{field}[{index}] is {value}, not a finite number")]
    NonFinite {
        /// `k`, `r`, `p` or `d`.
        field: &'static str,
        /// Row-major index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// The declared image size is zero or beyond [`MAX_SIDE`] / [`MAX_PIXELS`].
    #[error("camera_info size {width}x{height} (after binning) is not an image size rectification takes (1 to {MAX_SIDE} a side, at most {MAX_PIXELS} pixels)")]
    Size {
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
    },
    /// An entry of K or P that must be 0 or 1 is not.
    #[error("camera_info.{field}[{index}] is {value} but must be {expected}: K is [fx 0 cx; 0 fy cy; 0 0 1], P [fx' 0 cx' Tx; 0 fy' cy' Ty; 0 0 1 0]")]
    Form {
        /// `k` or `p`.
        field: &'static str,
        /// Row-major index.
        index: usize,
        /// The value.
        value: f64,
        /// What it must be.
        expected: f64,
    },
    /// A focal length is zero or negative.
    #[error("camera_info.{field}: focal lengths fx {fx} and fy {fy} must be positive")]
    Focal {
        /// `k` or `p`.
        field: &'static str,
        /// Focal length along x.
        fx: f64,
        /// Focal length along y.
        fy: f64,
    },
    /// R is not a rotation.
    #[error("camera_info.r is not a rotation: RᵀR is {orthonormality:e} from the identity and det R is {det} (tolerance {ROTATION_TOLERANCE:e})")]
    NotRotation {
        /// The largest entry of `|RᵀR - I|`.
        orthonormality: f64,
        /// The determinant.
        det: f64,
    },
    /// D has the wrong number of coefficients for the model.
    #[error("camera_info.d has {count} coefficients; distortion_model {model:?} takes {expected}")]
    CoefficientCount {
        /// The model name.
        model: String,
        /// How many D has.
        count: usize,
        /// What the model takes.
        expected: &'static str,
    },
    /// The model name is none this rectification knows.
    #[error("distortion_model {model:?} is not plumb_bob, rational_polynomial or equidistant")]
    UnknownModel {
        /// The model name.
        model: String,
    },
    /// The binning leaves no pixel.
    #[error("camera_info binning {x}x{y} leaves no pixel of the {width}x{height} image")]
    Binning {
        /// `binning_x`.
        x: u32,
        /// `binning_y`.
        y: u32,
        /// `width`.
        width: u32,
        /// `height`.
        height: u32,
    },
    /// A region of interest other than the full image.
    #[error("camera_info.roi {}x{} at ({}, {}) is a sub-window of the {width}x{height} image; rectifying a region of interest is not supported (publish the full image, roi all zero)", roi.width, roi.height, roi.x_offset, roi.y_offset)]
    Roi {
        /// The region.
        roi: RegionOfInterest,
        /// `width`.
        width: u32,
        /// `height`.
        height: u32,
    },
}

impl CameraModel {
    /// The model of `info`, checked as the module's header says.
    pub fn from_camera_info(info: &CameraInfo) -> Result<Self, CalibrationError> {
        for (field, values) in [
            ("k", &info.k[..]),
            ("r", &info.r),
            ("p", &info.p),
            ("d", &info.d),
        ] {
            if let Some((index, value)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(CalibrationError::NonFinite {
                    field,
                    index,
                    value: *value,
                });
            }
        }
        check_roi(info)?;
        let bx = info.binning_x.max(1);
        let by = info.binning_y.max(1);
        let (width, height) = (info.width / bx, info.height / by);
        if (width == 0 || height == 0) && info.width > 0 && info.height > 0 {
            return Err(CalibrationError::Binning {
                x: bx,
                y: by,
                width: info.width,
                height: info.height,
            });
        }
        if width == 0
            || height == 0
            || width > MAX_SIDE
            || height > MAX_SIDE
            || width as u64 * height as u64 > MAX_PIXELS
        {
            return Err(CalibrationError::Size { width, height });
        }
        let (sx, sy) = (bx as f64, by as f64);
        let k = pinhole(&info.k, "k", 3)?;
        let p = pinhole(&info.p, "p", 4)?;
        form("p", 11, info.p[11], 0.0)?;
        let r = DMat3::from_cols_array(&info.r).transpose();
        check_rotation(r)?;
        let scale = |c: Pinhole| Pinhole {
            fx: c.fx / sx,
            fy: c.fy / sy,
            cx: c.cx / sx,
            cy: c.cy / sy,
        };
        Ok(Self {
            width,
            height,
            k: scale(k),
            distortion: distortion(&info.distortion_model, &info.d)?,
            r,
            p: scale(p),
            tx: info.p[3] / sx,
            ty: info.p[7] / sy,
        })
    }

    /// Columns of the images (raw and rectified).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Rows of the images.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The raw image's intrinsics K.
    pub fn k(&self) -> Pinhole {
        self.k
    }

    /// The lens model D.
    pub fn distortion(&self) -> Distortion {
        self.distortion
    }

    /// The rectification rotation R (raw camera frame to rectified frame).
    pub fn r(&self) -> DMat3 {
        self.r
    }

    /// The rectified images' intrinsics, P's left 3x3.
    pub fn p(&self) -> Pinhole {
        self.p
    }

    /// P's translation column (`Tx`, `Ty`): `-fx' * baseline` and 0 for a right camera.
    pub fn translation(&self) -> (f64, f64) {
        (self.tx, self.ty)
    }

    /// Whether the images are rectified already (D zero, R identity, P's 3x3 equal to K):
    /// no table, images pass through as they are.
    pub fn is_rectified(&self) -> bool {
        let r_identity = (self.r - DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .all(|v| v.abs() <= 1e-9);
        let (k, p) = (self.k, self.p);
        let p_is_k = [k.fx - p.fx, k.fy - p.fy, k.cx - p.cx, k.cy - p.cy]
            .iter()
            .all(|v| v.abs() <= 1e-6);
        self.distortion.is_zero() && r_identity && p_is_k
    }

    /// The raw-image pixel that rectified pixel `px` samples (OpenCV's
    /// `initUndistortRectifyMap`: `(P₃ R)⁻¹`, the lens model, K), or `None` when the
    /// rectified pixel's ray is one the lens cannot image. `ray_from_rectified` is
    /// `(P₃ R)⁻¹`, passed in so a table computes it once.
    pub(super) fn raw_of_rectified(&self, ray_from_rectified: &DMat3, px: DVec2) -> Option<DVec2> {
        let ray = *ray_from_rectified * px.extend(1.0);
        self.distortion.distort_ray(ray).map(|d| self.k.to_pixel(d))
    }

    /// The rectified pixel that raw pixel `px` sees (the lens model inverted, then R and
    /// P), or `None` when its ray has no rectified pixel (behind the rectified image plane,
    /// or where the lens model has no inverse).
    pub(super) fn rectified_of_raw(&self, px: DVec2) -> Option<DVec2> {
        let ray = self.distortion.undistort(self.k.to_normalised(px))?;
        let rectified = self.p.matrix() * self.r * ray;
        (rectified.z > 0.0).then(|| DVec2::new(rectified.x, rectified.y) / rectified.z)
    }

    /// `(P₃ R)⁻¹`: rectified pixel to the ray in the raw camera's frame.
    pub(super) fn ray_from_rectified(&self) -> DMat3 {
        (self.p.matrix() * self.r).inverse()
    }
}

/// A region of interest must be all zero or the full image.
fn check_roi(info: &CameraInfo) -> Result<(), CalibrationError> {
    let roi = info.roi;
    let all_zero = (roi.x_offset, roi.y_offset, roi.width, roi.height) == (0, 0, 0, 0);
    let full =
        (roi.x_offset, roi.y_offset, roi.width, roi.height) == (0, 0, info.width, info.height);
    if all_zero || full {
        Ok(())
    } else {
        Err(CalibrationError::Roi {
            roi,
            width: info.width,
            height: info.height,
        })
    }
}

/// `m[index]` must be `expected`.
fn form(
    field: &'static str,
    index: usize,
    value: f64,
    expected: f64,
) -> Result<(), CalibrationError> {
    if (value - expected).abs() <= FORM_TOLERANCE {
        Ok(())
    } else {
        Err(CalibrationError::Form {
            field,
            index,
            value,
            expected,
        })
    }
}

/// The pinhole of a row-major matrix of rows `stride` long whose left 3x3 is
/// `[fx 0 cx; 0 fy cy; 0 0 1]`, its fixed entries checked.
fn pinhole(m: &[f64], field: &'static str, stride: usize) -> Result<Pinhole, CalibrationError> {
    for (row, col, expected) in [
        (0, 1, 0.0),
        (1, 0, 0.0),
        (2, 0, 0.0),
        (2, 1, 0.0),
        (2, 2, 1.0),
    ] {
        let index = row * stride + col;
        form(field, index, m[index], expected)?;
    }
    let (fx, fy) = (m[0], m[stride + 1]);
    if !(fx > 0.0 && fy > 0.0) {
        return Err(CalibrationError::Focal { field, fx, fy });
    }
    Ok(Pinhole {
        fx,
        fy,
        cx: m[2],
        cy: m[stride + 2],
    })
}

/// R must be orthonormal with determinant +1.
fn check_rotation(r: DMat3) -> Result<(), CalibrationError> {
    let orthonormality = (r.transpose() * r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let det = r.determinant();
    if orthonormality <= ROTATION_TOLERANCE && (det - 1.0).abs() <= ROTATION_TOLERANCE {
        Ok(())
    } else {
        Err(CalibrationError::NotRotation {
            orthonormality,
            det,
        })
    }
}

/// The lens model named `model` with coefficients `d`.
fn distortion(model: &str, d: &[f64]) -> Result<Distortion, CalibrationError> {
    let count_error = |expected| CalibrationError::CoefficientCount {
        model: model.to_owned(),
        count: d.len(),
        expected,
    };
    if d.is_empty() {
        return Ok(Distortion::None);
    }
    match model {
        "plumb_bob" => match d.len() {
            4 => Ok(Distortion::PlumbBob([d[0], d[1], d[2], d[3], 0.0])),
            5 => Ok(Distortion::PlumbBob([d[0], d[1], d[2], d[3], d[4]])),
            _ => Err(count_error(
                "5 (k1 k2 p1 p2 k3) or 4 (k3 = 0); 8 is rational_polynomial",
            )),
        },
        "rational_polynomial" => <[f64; 8]>::try_from(d)
            .map(Distortion::RationalPolynomial)
            .map_err(|_| count_error("8 (k1 k2 p1 p2 k3 k4 k5 k6)")),
        "equidistant" => <[f64; 4]>::try_from(d)
            .map(Distortion::Equidistant)
            .map_err(|_| count_error("4 (k1 k2 k3 k4)")),
        "" if d.iter().all(|c| *c == 0.0) => Ok(Distortion::None),
        _ => Err(CalibrationError::UnknownModel {
            model: model.to_owned(),
        }),
    }
}

#[cfg(test)]
#[path = "camera_tests.rs"]
mod tests;
