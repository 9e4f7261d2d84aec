//! Camera geometry the network needs as constant tensors: viewing rays of a feature grid,
//! the plane-sweep sampling points between two views, the nearest views by translation, and
//! the rotations that carry camera-frame Gaussians into the bin's frame. Computed in `f64`
//! on the CPU (the cameras are inputs, not learned) and handed to candle as `f32`.

use candle_core::{Device, Result, Tensor};
use glam::{DMat3, DQuat, DVec3};
use renderer::Camera;

/// Where pixel `(x, y)` of a grid with `stride` lies in the image: `(stride x, stride y)`.
fn ray(camera: &Camera, stride: usize, x: usize, y: usize) -> DVec3 {
    let k = camera.intrinsics;
    let s = stride as f64;
    DVec3::new(
        (s * x as f64 - k.cx as f64) / k.fx as f64,
        (s * y as f64 - k.cy as f64) / k.fy as f64,
        1.0,
    )
}

/// Camera-frame viewing rays (z = 1) of an `h` x `w` grid with `stride`, as `(3, h w)`.
pub fn rays(camera: &Camera, stride: usize, h: usize, w: usize, device: &Device) -> Result<Tensor> {
    let mut data = vec![0f32; 3 * h * w];
    for y in 0..h {
        for x in 0..w {
            let r = ray(camera, stride, x, y);
            for (c, v) in r.to_array().into_iter().enumerate() {
                data[c * h * w + y * w + x] = v as f32;
            }
        }
    }
    Tensor::from_vec(data, (3, h * w), device)
}

/// The rotation of camera-frame vectors into the world (bin) frame.
pub fn camera_to_world(camera: &Camera) -> DMat3 {
    camera.rotation.as_dmat3().transpose()
}

/// The 4x4 matrix `L(q)` with `L(q) p = q * p` (quaternions as `w x y z`), for `q` the
/// camera's orientation: it turns a rotation predicted in the camera frame into one in the
/// world frame.
pub fn orientation_matrix(camera: &Camera) -> [[f32; 4]; 4] {
    let q = DQuat::from_mat3(&camera_to_world(camera)).normalize();
    let (w, x, y, z) = (q.w as f32, q.x as f32, q.y as f32, q.z as f32);
    [[w, -x, -y, -z], [x, w, -z, y], [y, z, w, -x], [z, -y, x, w]]
}

/// The plane-sweep points from reference camera `reference` into `source`: for each depth
/// in `depths` and each pixel of the reference's `h` x `w` grid (both with `stride`), the
/// point at that depth on the pixel's ray, projected into the source's grid, in pixel
/// coordinates (`x, y` interleaved in depth, row, column order: `ops::grid_sample`'s
/// `(1, D h, w, 2)` grid). Points behind or at the source camera get NaN, which samples zero.
pub fn sweep_points(
    reference: &Camera,
    source: &Camera,
    depths: &[f64],
    stride: usize,
    (h, w): (usize, usize),
) -> Vec<f32> {
    let to_source = source.rotation.as_dmat3() * camera_to_world(reference);
    let offset =
        source.rotation.as_dmat3() * (reference.position.as_dvec3() - source.position.as_dvec3());
    let k = source.intrinsics;
    let s = stride as f64;
    let mut data = Vec::with_capacity(depths.len() * h * w * 2);
    for &d in depths {
        for y in 0..h {
            for x in 0..w {
                let p = to_source * (ray(reference, stride, x, y) * d) + offset;
                if p.z > 1e-3 {
                    data.push(((k.fx as f64 * p.x / p.z + k.cx as f64) / s) as f32);
                    data.push(((k.fy as f64 * p.y / p.z + k.cy as f64) / s) as f32);
                } else {
                    data.extend([f32::NAN, f32::NAN]);
                }
            }
        }
    }
    data
}

/// For each view, the indices of its `n` nearest other views by camera translation (ties to
/// the lower index), `n` capped at the number of other views.
pub fn nearest_views(cameras: &[Camera], n: usize) -> Vec<Vec<usize>> {
    (0..cameras.len())
        .map(|i| {
            let mut others: Vec<usize> = (0..cameras.len()).filter(|&j| j != i).collect();
            let dist = |j: &usize| cameras[i].position.distance(cameras[*j].position);
            others.sort_by(|a, b| dist(a).total_cmp(&dist(b)).then(a.cmp(b)));
            others.truncate(n);
            others
        })
        .collect()
}

/// A camera of the unit tests: 80x40, fx 100, looking down +z from `(x, 0, 0)`.
#[cfg(test)]
pub(crate) fn test_camera(x: f32) -> Camera {
    let k = renderer::Intrinsics {
        fx: 100.0,
        fy: 100.0,
        cx: 40.0,
        cy: 20.0,
        width: 80,
        height: 40,
    };
    Camera::from_camera_to_world(k, glam::Quat::IDENTITY, glam::Vec3::new(x, 0.0, 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweep_of_a_rectified_pair_shifts_by_the_disparity() {
        let (left, right) = (test_camera(0.0), test_camera(0.5));
        // Depth 10 m, baseline 0.5 m, fx 100: disparity 5 px, 1.25 px on the 1/4 grid.
        let v = sweep_points(&left, &right, &[10.0], 4, (10, 20));
        let (x, y) = (3usize, 2usize);
        let i = (y * 20 + x) * 2;
        assert!((v[i] - (x as f32 - 1.25)).abs() < 1e-5, "{}", v[i]);
        assert!((v[i + 1] - y as f32).abs() < 1e-5);
    }

    #[test]
    fn nearest_views_follow_translation() {
        let cams = [
            test_camera(0.0),
            test_camera(0.5),
            test_camera(5.0),
            test_camera(5.5),
        ];
        let n = nearest_views(&cams, 2);
        assert_eq!(n[0], vec![1, 2]);
        assert_eq!(n[3], vec![2, 1]);
        assert_eq!(nearest_views(&cams[..2], 2)[0], vec![1]);
    }

    #[test]
    fn orientation_of_an_identity_camera_is_identity() {
        let m = orientation_matrix(&test_camera(3.0));
        for (r, row) in m.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                assert!((v - if r == c { 1.0 } else { 0.0 }).abs() < 1e-6);
            }
        }
    }
}
