//! The few small fixed-size linear-algebra helpers the rasterizer needs, generic over the
//! scalar so `f32` and `f64` share one implementation (glam is `f32`-or-`f64` by type, not
//! by parameter).

use crate::real::Real;

/// A 3x3 matrix, rows.
pub type M3<T> = [[T; 3]; 3];

/// `a * b`.
pub fn mul<T: Real>(a: &M3<T>, b: &M3<T>) -> M3<T> {
    let mut r = [[T::zero(); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    r
}

/// `a^T`.
pub fn transpose<T: Real>(a: &M3<T>) -> M3<T> {
    let mut r = [[T::zero(); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = a[j][i];
        }
    }
    r
}

/// `a * v`.
pub fn mul_vec<T: Real>(a: &M3<T>, v: &[T; 3]) -> [T; 3] {
    [0, 1, 2].map(|i| a[i][0] * v[0] + a[i][1] * v[1] + a[i][2] * v[2])
}

/// The rotation matrix of a unit quaternion in glam order (x, y, z, w).
pub fn quat_to_mat<T: Real>(q: &[T; 4]) -> M3<T> {
    let [x, y, z, w] = *q;
    let one = T::one();
    let two = T::c(2.0);
    [
        [
            one - two * (y * y + z * z),
            two * (x * y - w * z),
            two * (x * z + w * y),
        ],
        [
            two * (x * y + w * z),
            one - two * (x * x + z * z),
            two * (y * z - w * x),
        ],
        [
            two * (x * z - w * y),
            two * (y * z + w * x),
            one - two * (x * x + y * y),
        ],
    ]
}

/// Below this squared norm a quaternion is treated as the identity rotation.
pub const MIN_QUAT_NORM2: f64 = 1e-24;

/// Normalises a quaternion; a zero (or denormal) quaternion becomes the identity, the
/// documented rule for degenerate rotations.
pub fn normalize_quat<T: Real>(q: &[T; 4]) -> [T; 4] {
    let n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if n2 < T::c(MIN_QUAT_NORM2) {
        return [T::zero(), T::zero(), T::zero(), T::one()];
    }
    let inv = T::one() / n2.sqrt();
    q.map(|v| v * inv)
}

/// Gradient of a scalar with respect to the rotation matrix of a unit quaternion, carried
/// back to the quaternion itself (x, y, z, w), before normalisation.
pub fn quat_to_mat_backward<T: Real>(q: &[T; 4], g: &M3<T>) -> [T; 4] {
    let [x, y, z, w] = *q;
    let two = T::c(2.0);
    let gx = two
        * (-two * x * (g[1][1] + g[2][2])
            + y * (g[0][1] + g[1][0])
            + z * (g[0][2] + g[2][0])
            + w * (g[2][1] - g[1][2]));
    let gy = two
        * (x * (g[0][1] + g[1][0]) - two * y * (g[0][0] + g[2][2])
            + z * (g[1][2] + g[2][1])
            + w * (g[0][2] - g[2][0]));
    let gz = two
        * (x * (g[0][2] + g[2][0]) + y * (g[1][2] + g[2][1]) - two * z * (g[0][0] + g[1][1])
            + w * (g[1][0] - g[0][1]));
    let gw = two * (x * (g[2][1] - g[1][2]) + y * (g[0][2] - g[2][0]) + z * (g[1][0] - g[0][1]));
    [gx, gy, gz, gw]
}

/// Gradient through [`normalize_quat`]: from the unit quaternion back to the raw one.
pub fn normalize_quat_backward<T: Real>(q_raw: &[T; 4], g_unit: &[T; 4]) -> [T; 4] {
    let n2 = q_raw[0] * q_raw[0] + q_raw[1] * q_raw[1] + q_raw[2] * q_raw[2] + q_raw[3] * q_raw[3];
    if n2 < T::c(MIN_QUAT_NORM2) {
        return [T::zero(); 4];
    }
    let inv = T::one() / n2.sqrt();
    let u = q_raw.map(|v| v * inv);
    let dot = u[0] * g_unit[0] + u[1] * g_unit[1] + u[2] * g_unit[2] + u[3] * g_unit[3];
    [0, 1, 2, 3].map(|i| (g_unit[i] - u[i] * dot) * inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_matrix_matches_glam() {
        let q = glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 2.0);
        let m = quat_to_mat(&q.to_array());
        let g = glam::DMat3::from_quat(q);
        for (i, row) in m.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                assert!((v - g.col(j)[i]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn quaternion_backward_matches_finite_differences() {
        let q = [0.2f64, -0.4, 0.1, 0.8];
        let g = [[0.3, -1.0, 0.5], [0.7, 0.2, -0.1], [-0.6, 0.4, 0.9]];
        let loss = |q: &[f64; 4]| {
            let m = quat_to_mat(&normalize_quat(q));
            (0..3)
                .flat_map(|i| (0..3).map(move |j| (i, j)))
                .map(|(i, j)| m[i][j] * g[i][j])
                .sum::<f64>()
        };
        let analytic = normalize_quat_backward(&q, &quat_to_mat_backward(&normalize_quat(&q), &g));
        for k in 0..4 {
            let (mut a, mut b) = (q, q);
            a[k] += 1e-6;
            b[k] -= 1e-6;
            let fd = (loss(&a) - loss(&b)) / 2e-6;
            assert!(
                (fd - analytic[k]).abs() < 1e-7,
                "component {k}: fd {fd} analytic {}",
                analytic[k]
            );
        }
    }

    #[test]
    fn a_zero_quaternion_is_the_identity() {
        assert_eq!(normalize_quat(&[0.0f32; 4]), [0.0, 0.0, 0.0, 1.0]);
        assert_eq!(normalize_quat_backward(&[0.0f64; 4], &[1.0; 4]), [0.0; 4]);
    }
}
