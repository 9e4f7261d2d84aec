//! The three lens models of `sensor_msgs/CameraInfo` as maps between viewing rays and
//! normalised distorted image coordinates (`((u - cx) / fx, (v - cy) / fy)` of the raw
//! image), in both directions: forward as OpenCV's `initUndistortRectifyMap` evaluates them,
//! inverse by Newton's method (what makes raw images from rectified ones).
//!
//! - `plumb_bob`: Brown-Conrady, radial k1 k2 k3 and tangential p1 p2.
//! - `rational_polynomial`: the same with the radial factor divided by `1 + k4 r² + k5 r⁴ +
//!   k6 r⁶` (OpenCV's `CALIB_RATIONAL_MODEL`).
//! - `equidistant`: OpenCV's fisheye model, `θd = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)` with
//!   θ the ray's angle to the optical axis; it sees rays at and beyond 90 degrees.

use glam::{DVec2, DVec3};

/// A lens model with its coefficients, in the order of `CameraInfo.d`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distortion {
    /// No distortion: the pinhole model.
    None,
    /// `plumb_bob`: `[k1, k2, p1, p2, k3]`.
    PlumbBob([f64; 5]),
    /// `rational_polynomial`: `[k1, k2, p1, p2, k3, k4, k5, k6]`.
    RationalPolynomial([f64; 8]),
    /// `equidistant` (OpenCV fisheye): `[k1, k2, k3, k4]`.
    Equidistant([f64; 4]),
}

/// Newton's method stops when the residual is below this times `1 + |d|` (normalised
/// units: 1e-12 of a focal length, far below a pixel at any focal length a camera has).
const NEWTON_TOLERANCE: f64 = 1e-12;
/// Newton steps before a point is declared to have no solution.
const NEWTON_STEPS: usize = 50;

impl Distortion {
    /// Whether every coefficient is zero: the lens is a pinhole.
    pub fn is_zero(&self) -> bool {
        self.coefficients().iter().all(|c| *c == 0.0)
    }

    /// The coefficients in `CameraInfo.d` order (empty for [`Distortion::None`]).
    pub fn coefficients(&self) -> &[f64] {
        match self {
            Self::None => &[],
            Self::PlumbBob(d) => d,
            Self::RationalPolynomial(d) => d,
            Self::Equidistant(d) => d,
        }
    }

    /// Where the ray `ray` (camera frame, z forward) lands in normalised distorted
    /// coordinates, or `None` when the model cannot image it: the pinhole models image only
    /// rays in front of the camera (z > 0); the fisheye model every ray but the one straight
    /// behind. Non-finite results (huge coefficients) come back as they are; the caller
    /// treats them as off the image.
    pub fn distort_ray(&self, ray: DVec3) -> Option<DVec2> {
        match self {
            Self::Equidistant(k) => {
                let r = ray.x.hypot(ray.y);
                if r == 0.0 {
                    return (ray.z > 0.0).then_some(DVec2::ZERO);
                }
                let theta = r.atan2(ray.z);
                Some(DVec2::new(ray.x, ray.y) * (fisheye_theta_d(k, theta) / r))
            }
            _ => (ray.z > 0.0).then(|| self.distort_plane(DVec2::new(ray.x, ray.y) / ray.z)),
        }
    }

    /// The ray (not normalised) that lands on normalised distorted coordinates `d`, or
    /// `None` when Newton's method finds no solution on the lens's valid branch (where the
    /// model folds over, as very strong barrel distortion does towards the corners).
    pub fn undistort(&self, d: DVec2) -> Option<DVec3> {
        if !d.is_finite() {
            return None;
        }
        match self {
            Self::None => Some(d.extend(1.0)),
            Self::Equidistant(k) => fisheye_undistort(k, d),
            _ => self.plane_undistort(d).map(|p| p.extend(1.0)),
        }
    }

    /// The pinhole models' distortion of a point on the z = 1 plane, term for term as
    /// OpenCV's `initUndistortRectifyMap` (the rational factor is 1 for `plumb_bob`).
    fn distort_plane(&self, p: DVec2) -> DVec2 {
        let k = match self {
            Self::PlumbBob([k1, k2, p1, p2, k3]) => [*k1, *k2, *p1, *p2, *k3, 0.0, 0.0, 0.0],
            Self::RationalPolynomial(k) => *k,
            Self::None | Self::Equidistant(_) => return p,
        };
        let [k1, k2, p1, p2, k3, k4, k5, k6] = k;
        let (x, y) = (p.x, p.y);
        let (x2, y2) = (x * x, y * y);
        let r2 = x2 + y2;
        let xy2 = 2.0 * x * y;
        let kr = (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2) / (1.0 + ((k6 * r2 + k5) * r2 + k4) * r2);
        DVec2::new(
            x * kr + p1 * xy2 + p2 * (r2 + 2.0 * x2),
            y * kr + p1 * (r2 + 2.0 * y2) + p2 * xy2,
        )
    }

    /// Newton's method on [`Self::distort_plane`] from the distorted point itself, with a
    /// central-difference Jacobian and step halving when a step makes the residual grow.
    /// The solution must sit where the map keeps orientation (positive Jacobian determinant
    /// and diagonal): past a fold the same distorted point has a second, unphysical preimage.
    fn plane_undistort(&self, d: DVec2) -> Option<DVec2> {
        let residual = |p: DVec2| self.distort_plane(p) - d;
        let tolerance = NEWTON_TOLERANCE * (1.0 + d.length());
        let mut p = d;
        let mut f = residual(p);
        for _ in 0..NEWTON_STEPS {
            if !f.is_finite() {
                return None;
            }
            let j = self.jacobian(p);
            if f.length() < tolerance {
                let valid = j.0.x > 0.0 && j.1.y > 0.0 && j.0.x * j.1.y - j.1.x * j.0.y > 0.0;
                return valid.then_some(p);
            }
            let step = solve2(j, f)?;
            let mut scale = 1.0;
            loop {
                let next = p - step * scale;
                let g = residual(next);
                if g.is_finite() && g.length() < f.length() {
                    p = next;
                    f = g;
                    break;
                }
                scale *= 0.5;
                if scale < 1e-6 {
                    return None;
                }
            }
        }
        None
    }

    /// The Jacobian of [`Self::distort_plane`] at `p` as its two columns (d/dx, d/dy).
    fn jacobian(&self, p: DVec2) -> (DVec2, DVec2) {
        let h = 1e-7 * (1.0 + p.abs().max_element());
        let dx = (self.distort_plane(p + DVec2::X * h) - self.distort_plane(p - DVec2::X * h))
            / (2.0 * h);
        let dy = (self.distort_plane(p + DVec2::Y * h) - self.distort_plane(p - DVec2::Y * h))
            / (2.0 * h);
        (dx, dy)
    }
}

/// `θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)`.
fn fisheye_theta_d(k: &[f64; 4], theta: f64) -> f64 {
    let t2 = theta * theta;
    theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))
}

/// d θd / d θ.
fn fisheye_theta_d_slope(k: &[f64; 4], theta: f64) -> f64 {
    let t2 = theta * theta;
    1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])))
}

/// The fisheye model's inverse: θ from θd by Newton's method (θd itself to start), on the
/// branch where θd grows with θ, for θ in [0, π]; the ray may point sideways or backwards.
fn fisheye_undistort(k: &[f64; 4], d: DVec2) -> Option<DVec3> {
    let theta_d = d.length();
    if theta_d == 0.0 {
        return Some(DVec3::Z);
    }
    let mut theta = theta_d.min(std::f64::consts::PI);
    for _ in 0..NEWTON_STEPS {
        let f = fisheye_theta_d(k, theta) - theta_d;
        let slope = fisheye_theta_d_slope(k, theta);
        if !(f.is_finite() && slope > 0.0) {
            return None;
        }
        if f.abs() < NEWTON_TOLERANCE * (1.0 + theta_d) {
            let dir = d / theta_d;
            return Some((dir * theta.sin()).extend(theta.cos()));
        }
        theta = (theta - f / slope).clamp(0.0, std::f64::consts::PI);
    }
    None
}

/// `j⁻¹ f` for the 2x2 matrix with columns `j`, or `None` when it is singular.
fn solve2(j: (DVec2, DVec2), f: DVec2) -> Option<DVec2> {
    let det = j.0.x * j.1.y - j.1.x * j.0.y;
    if !(det.is_finite() && det.abs() > 1e-300) {
        return None;
    }
    Some(DVec2::new(j.1.y * f.x - j.1.x * f.y, j.0.x * f.y - j.0.y * f.x) / det)
}
