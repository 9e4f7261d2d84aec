//! The pinhole camera: intrinsics plus a world-to-camera pose in the OpenCV convention
//! (x right, y down, z forward; pixel centres at integer coordinates, as KITTI's `P_rect`).

use glam::{Mat3, Quat, Vec3};

use crate::real::Real;

/// Pinhole intrinsics in pixels and the image size they apply to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels (pixel centres at integers).
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

impl Intrinsics {
    /// Square pixels, principal point at the image centre, the given horizontal field of view.
    pub fn from_hfov(width: u32, height: u32, hfov_degrees: f32) -> Self {
        let f = 0.5 * width as f32 / (0.5 * hfov_degrees.to_radians()).tan();
        Self {
            fx: f,
            fy: f,
            cx: (width as f32 - 1.0) * 0.5,
            cy: (height as f32 - 1.0) * 0.5,
            width,
            height,
        }
    }

    /// The same optics at another resolution (principal point and focal lengths scaled).
    pub fn scaled(&self, width: u32, height: u32) -> Self {
        let sx = width as f32 / self.width as f32;
        let sy = height as f32 / self.height as f32;
        Self {
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            width,
            height,
        }
    }
}

/// A camera: intrinsics and the rigid world-to-camera transform, held as a rotation and the
/// camera centre so that `x_cam = rotation * (x_world - position)`. Subtracting the centre
/// first is exact in `f32` for points near the camera, so frames far from the origin lose
/// no precision to cancellation (the translation form `R x + t` would).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Intrinsics and image size.
    pub intrinsics: Intrinsics,
    /// World-to-camera rotation (orthonormal).
    pub rotation: Mat3,
    /// Camera centre in world coordinates.
    pub position: Vec3,
}

impl Camera {
    /// A camera at `position` whose axes are given by `camera_to_world` rotation.
    pub fn from_camera_to_world(intrinsics: Intrinsics, rotation: Quat, position: Vec3) -> Self {
        Self {
            intrinsics,
            rotation: Mat3::from_quat(rotation.normalize()).transpose(),
            position,
        }
    }

    /// A camera from a world-to-camera rotation and translation (`x_cam = R x + t`).
    pub fn from_world_to_camera(intrinsics: Intrinsics, rotation: Mat3, translation: Vec3) -> Self {
        let r = rotation.as_dmat3();
        Self {
            intrinsics,
            rotation,
            position: (-(r.transpose() * translation.as_dvec3())).as_vec3(),
        }
    }

    /// A camera at the origin looking down +z (identity pose): the benchmark's default.
    pub fn identity(intrinsics: Intrinsics) -> Self {
        Self {
            intrinsics,
            rotation: Mat3::IDENTITY,
            position: Vec3::ZERO,
        }
    }

    /// The world-to-camera translation `t` of `x_cam = R x + t`.
    pub fn translation(&self) -> Vec3 {
        -(self.rotation * self.position)
    }

    /// The parameters in the rasterizer's scalar type.
    pub fn params<T: Real>(&self) -> CameraParams<T> {
        let r = self.rotation.transpose().to_cols_array_2d(); // rows of `rotation`
        let k = &self.intrinsics;
        let c = |v: f32| T::c(v as f64);
        CameraParams {
            fx: c(k.fx),
            fy: c(k.fy),
            cx: c(k.cx),
            cy: c(k.cy),
            width: k.width,
            height: k.height,
            rotation: r.map(|row| row.map(c)),
            position: self.position.to_array().map(c),
        }
    }
}

/// A camera as plain arrays in scalar `T`: what the CPU rasterizer reads. `rotation` is row
/// major; `x_cam = rotation * (x_world - position)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraParams<T> {
    /// Focal length along x, pixels.
    pub fx: T,
    /// Focal length along y, pixels.
    pub fy: T,
    /// Principal point x, pixels.
    pub cx: T,
    /// Principal point y, pixels.
    pub cy: T,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// World-to-camera rotation, rows.
    pub rotation: [[T; 3]; 3],
    /// Camera centre, world coordinates.
    pub position: [T; 3],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_to_world_round_trips_the_position() {
        let k = Intrinsics::from_hfov(64, 48, 90.0);
        let p = Vec3::new(1.0e3, -2.0, 5.0);
        let cam = Camera::from_camera_to_world(k, Quat::from_rotation_y(0.3), p);
        let back = Camera::from_world_to_camera(k, cam.rotation, cam.translation());
        assert!((back.position - p).length() < 1e-2);
        // A point straight ahead of the camera lands on the principal point.
        let ahead = p + Quat::from_rotation_y(0.3) * Vec3::Z * 10.0;
        let pc = cam.rotation * (ahead - cam.position);
        assert!(pc.x.abs() < 1e-3 && pc.y.abs() < 1e-3 && (pc.z - 10.0).abs() < 1e-3);
    }

    #[test]
    fn hfov_of_ninety_degrees_puts_the_edge_at_forty_five() {
        let k = Intrinsics::from_hfov(100, 50, 90.0);
        assert!((k.fx - 50.0).abs() < 1e-4);
        let s = k.scaled(200, 100);
        assert!((s.fx - 100.0).abs() < 1e-4 && (s.cx - 99.5).abs() < 1e-4);
    }
}
