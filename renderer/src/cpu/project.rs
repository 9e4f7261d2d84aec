//! Projection: one 3D Gaussian to its screen-space footprint (EWA splatting, as 3DGS).
//!
//! Covariance from scale and rotation, into the camera frame, through the perspective
//! Jacobian (with 3DGS's clamp of the view-space direction to 1.3x the field of view), plus
//! [`COV2D_DILATION`] px^2; the conic is its inverse, the radius is 3 sigma of its larger
//! eigenvalue, the tile rectangle covers that radius. Pixel centres sit at integer
//! coordinates (OpenCV), so `mean2d = (fx x / z + cx, fy y / z + cy)`.
//!
//! Culling rules (the documented handling of bad input): a Gaussian with any non-finite
//! parameter, a centre outside `[near, far]` in camera z, a non-positive-definite or
//! non-finite screen covariance, or an empty tile rectangle is skipped; a zero quaternion is
//! the identity rotation; opacity is clamped to [0, 1].

use super::math::{self, M3};
use super::COV2D_DILATION;
use super::TILE_SIZE;
use crate::camera::CameraParams;
use crate::gaussians::SplatsView;
use crate::output::RenderSettings;
use crate::real::Real;

/// A Gaussian as the compositor sees it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Projected<T> {
    /// Centre in pixels.
    pub mean2d: [T; 2],
    /// Inverse screen covariance (a, b, c) = ((0,0), (0,1), (1,1)).
    pub conic: [T; 3],
    /// Camera-space z of the centre: the sort key and the depth it contributes.
    pub depth: T,
    /// Opacity, clamped to [0, 1].
    pub opacity: T,
    /// Colour.
    pub color: [T; 3],
    /// Confidence.
    pub confidence: T,
    /// 3-sigma radius in pixels (rounded up).
    pub radius: T,
    /// First tile (x, y) the footprint touches.
    pub tile_min: [u32; 2],
    /// One past the last tile (x, y) it touches.
    pub tile_max: [u32; 2],
}

impl<T> Projected<T> {
    /// Number of tiles the footprint touches.
    pub fn tile_count(&self) -> u32 {
        (self.tile_max[0] - self.tile_min[0]) * (self.tile_max[1] - self.tile_min[1])
    }
}

/// The frustum clamp of 3DGS: the direction x/z, y/z used in the Jacobian is limited to
/// 1.3x the half field of view beyond the principal point, so Gaussians far outside the
/// image do not blow up. Returns the clamped ratios and whether each was inside (free).
fn clamped_direction<T: Real>(cam: &CameraParams<T>, pc: &[T; 3]) -> ([T; 2], [bool; 2]) {
    let w = T::c(cam.width as f64);
    let h = T::c(cam.height as f64);
    let margin = T::c(0.3 * 0.5);
    let lim_x_pos = (w - cam.cx) / cam.fx + margin * w / cam.fx;
    let lim_x_neg = cam.cx / cam.fx + margin * w / cam.fx;
    let lim_y_pos = (h - cam.cy) / cam.fy + margin * h / cam.fy;
    let lim_y_neg = cam.cy / cam.fy + margin * h / cam.fy;
    let u = pc[0] / pc[2];
    let v = pc[1] / pc[2];
    let uc = u.max(-lim_x_neg).min(lim_x_pos);
    let vc = v.max(-lim_y_neg).min(lim_y_pos);
    ([uc, vc], [uc == u, vc == v])
}

/// The 2x3 perspective Jacobian at camera point `pc` with clamped direction `dir`.
fn jacobian<T: Real>(cam: &CameraParams<T>, z: T, dir: &[T; 2]) -> [[T; 3]; 2] {
    [
        [cam.fx / z, T::zero(), -cam.fx * dir[0] / z],
        [T::zero(), cam.fy / z, -cam.fy * dir[1] / z],
    ]
}

/// `M = R(q) diag(exp(log_scale))`, so the 3D covariance is `M M^T`.
fn scale_rotation<T: Real>(q_unit: &[T; 4], log_scale: &[T; 3]) -> (M3<T>, [T; 3], M3<T>) {
    let r = math::quat_to_mat(q_unit);
    let s = log_scale.map(|v| v.exp());
    let mut m = r;
    for row in m.iter_mut() {
        for k in 0..3 {
            row[k] = row[k] * s[k];
        }
    }
    (r, s, m)
}

/// Camera-frame covariance `W M M^T W^T` written as `(W M)(W M)^T`.
fn camera_covariance<T: Real>(w: &M3<T>, m: &M3<T>) -> M3<T> {
    let wm = math::mul(w, m);
    math::mul(&wm, &math::transpose(&wm))
}

/// `J S J^T` for the 2x3 `J` and symmetric 3x3 `S`, as (a, b, c).
fn project_cov<T: Real>(j: &[[T; 3]; 2], s: &M3<T>) -> [T; 3] {
    let js = [0, 1]
        .map(|r| [0, 1, 2].map(|c| j[r][0] * s[0][c] + j[r][1] * s[1][c] + j[r][2] * s[2][c]));
    let dot = |a: &[T; 3], b: &[T; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    [dot(&js[0], &j[0]), dot(&js[0], &j[1]), dot(&js[1], &j[1])]
}

fn all_finite<T: Real>(v: &[T]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Projects Gaussian `i`; `None` when a culling rule of the module applies.
pub fn project<T: Real>(
    s: &SplatsView<'_, T>,
    i: usize,
    cam: &CameraParams<T>,
    settings: &RenderSettings,
) -> Option<Projected<T>> {
    let (mean, log_scale, rot) = (&s.means[i], &s.log_scales[i], &s.rotations[i]);
    let (color, opacity, confidence) = (s.colors[i], s.opacities[i], s.confidences[i]);
    let finite = all_finite(mean)
        && all_finite(log_scale)
        && all_finite(rot)
        && all_finite(&color)
        && opacity.is_finite()
        && confidence.is_finite();
    if !finite {
        return None;
    }
    let rel = [0, 1, 2].map(|k| mean[k] - cam.position[k]);
    let pc = math::mul_vec(&cam.rotation, &rel);
    let z = pc[2];
    if !(z >= T::c(settings.near as f64) && z <= T::c(settings.far as f64)) {
        return None;
    }
    let (_, _, m) = scale_rotation(&math::normalize_quat(rot), log_scale);
    let cov_c = camera_covariance(&cam.rotation, &m);
    let (dir, _) = clamped_direction(cam, &pc);
    let j = jacobian(cam, z, &dir);
    let [a0, b, c0] = project_cov(&j, &cov_c);
    let a = a0 + T::c(COV2D_DILATION);
    let c = c0 + T::c(COV2D_DILATION);
    let det = a * c - b * b;
    if !det.is_finite() || det <= T::zero() {
        return None;
    }
    let conic = [c / det, -b / det, a / det];
    let mean2d = [cam.fx * pc[0] / z + cam.cx, cam.fy * pc[1] / z + cam.cy];
    let mid = T::c(0.5) * (a + c);
    let lambda = mid + (mid * mid - det).max(T::c(0.1)).sqrt();
    let radius = (T::c(3.0) * lambda.sqrt()).ceil();
    if !all_finite(&conic) || !all_finite(&mean2d) || !radius.is_finite() {
        return None;
    }
    let (tile_min, tile_max) = tile_rect(mean2d, radius, cam.width, cam.height);
    let projected = Projected {
        mean2d,
        conic,
        depth: z,
        opacity: opacity.max(T::zero()).min(T::one()),
        color,
        confidence,
        radius,
        tile_min,
        tile_max,
    };
    (projected.tile_count() > 0).then_some(projected)
}

/// The tiles a footprint of `radius` pixels around `mean2d` touches, clamped to the grid.
/// Clamping happens in floating point before the conversion, so huge or far-off footprints
/// convert without overflow (the GPU stage does the same).
pub fn tile_rect<T: Real>(
    mean2d: [T; 2],
    radius: T,
    width: u32,
    height: u32,
) -> ([u32; 2], [u32; 2]) {
    let grid = [width.div_ceil(TILE_SIZE), height.div_ceil(TILE_SIZE)];
    let t = T::c(TILE_SIZE as f64);
    let to_tile = |v: T, g: u32| v.max(T::zero()).min(T::c(g as f64)).to_u32().unwrap_or(0);
    let min = [0, 1].map(|k| to_tile(((mean2d[k] - radius) / t).floor(), grid[k]));
    let max = [0, 1].map(|k| to_tile(((mean2d[k] + radius + t - T::one()) / t).floor(), grid[k]));
    (min, max)
}

/// Gradients reaching one projected Gaussian from the compositor.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProjectedGrads<T> {
    /// d loss / d mean2d.
    pub mean2d: [T; 2],
    /// d loss / d (a, b, c) of the conic, `b` counted once as it appears in the exponent.
    pub conic: [T; 3],
    /// d loss / d depth (camera z).
    pub depth: T,
    /// d loss / d clamped opacity.
    pub opacity: T,
}

/// Gradients of one Gaussian's raw parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ParamGrads<T> {
    /// d loss / d mean.
    pub mean: [T; 3],
    /// d loss / d log scale.
    pub log_scale: [T; 3],
    /// d loss / d raw (unnormalised) quaternion, glam order.
    pub rotation: [T; 4],
    /// d loss / d opacity logit.
    pub opacity_logit: T,
}

/// Carries compositor gradients of Gaussian `i` back to its raw parameters. Radius and tile
/// rectangle are treated as constants, as in 3DGS.
pub fn project_backward<T: Real>(
    s: &SplatsView<'_, T>,
    i: usize,
    cam: &CameraParams<T>,
    g: &ProjectedGrads<T>,
) -> ParamGrads<T> {
    let (mean, log_scale, rot) = (&s.means[i], &s.log_scales[i], &s.rotations[i]);
    let rel = [0, 1, 2].map(|k| mean[k] - cam.position[k]);
    let pc = math::mul_vec(&cam.rotation, &rel);
    let z = pc[2];
    let q = math::normalize_quat(rot);
    let (r, scale, m) = scale_rotation(&q, log_scale);
    let w = &cam.rotation;
    let cov_c = camera_covariance(w, &m);
    let (dir, free) = clamped_direction(cam, &pc);
    let j = jacobian(cam, z, &dir);
    let [a0, b, c0] = project_cov(&j, &cov_c);
    let a = a0 + T::c(COV2D_DILATION);
    let c = c0 + T::c(COV2D_DILATION);
    let det = a * c - b * b;
    let qm = [[c / det, -b / det], [-b / det, a / det]];

    // Conic -> screen covariance: dL/dSigma2 = -Q G_Q Q, with G_Q symmetric (b split in two).
    let half = T::c(0.5);
    let gq = [
        [g.conic[0], half * g.conic[1]],
        [half * g.conic[1], g.conic[2]],
    ];
    let mul2 = |x: &[[T; 2]; 2], y: &[[T; 2]; 2]| {
        [0, 1].map(|r| [0, 1].map(|c| x[r][0] * y[0][c] + x[r][1] * y[1][c]))
    };
    let g2 = mul2(&mul2(&qm, &gq), &qm).map(|row| row.map(|v| -v));

    // Sigma2 = J Sigma_c J^T: dL/dSigma_c = J^T G2 J, dL/dJ = 2 G2 J Sigma_c.
    let mut g_cov_c = [[T::zero(); 3]; 3];
    for (r, row) in g_cov_c.iter_mut().enumerate() {
        for (cc, v) in row.iter_mut().enumerate() {
            for p in 0..2 {
                for k in 0..2 {
                    *v = *v + j[p][r] * g2[p][k] * j[k][cc];
                }
            }
        }
    }
    let mut g_j = [[T::zero(); 3]; 2];
    for (p, row) in g_j.iter_mut().enumerate() {
        for (cc, v) in row.iter_mut().enumerate() {
            let mut acc = T::zero();
            for k in 0..2 {
                for l in 0..3 {
                    acc = acc + g2[p][k] * j[k][l] * cov_c[l][cc];
                }
            }
            *v = T::c(2.0) * acc;
        }
    }

    // Sigma_c = W Sigma W^T, Sigma = M M^T: dL/dM = 2 W^T G_c W M.
    let g_cov = math::mul(&math::mul(&math::transpose(w), &g_cov_c), w);
    let g_m = math::mul(&g_cov, &m).map(|row| row.map(|v| T::c(2.0) * v));
    let mut g_r = [[T::zero(); 3]; 3];
    let mut g_log_scale = [T::zero(); 3];
    for row in 0..3 {
        for k in 0..3 {
            g_r[row][k] = g_m[row][k] * scale[k];
            g_log_scale[k] = g_log_scale[k] + g_m[row][k] * r[row][k] * scale[k];
        }
    }
    let rotation = math::normalize_quat_backward(rot, &math::quat_to_mat_backward(&q, &g_r));

    // Camera point: from mean2d, depth and the Jacobian (whose direction may be clamped).
    let z2 = z * z;
    let mut g_pc = [
        g.mean2d[0] * cam.fx / z,
        g.mean2d[1] * cam.fy / z,
        g.depth - g.mean2d[0] * cam.fx * pc[0] / z2 - g.mean2d[1] * cam.fy * pc[1] / z2,
    ];
    g_pc[2] = g_pc[2] - g_j[0][0] * cam.fx / z2 - g_j[1][1] * cam.fy / z2;
    for (k, f) in [(0usize, cam.fx), (1, cam.fy)] {
        let gj = g_j[k][2];
        if free[k] {
            // J_k2 = -f p_k / z^2.
            g_pc[k] = g_pc[k] - gj * f / z2;
            g_pc[2] = g_pc[2] + gj * T::c(2.0) * f * pc[k] / (z2 * z);
        } else {
            // J_k2 = -f dir_k / z with dir_k fixed by the clamp.
            g_pc[2] = g_pc[2] + gj * f * dir[k] / z2;
        }
    }
    let mean_grad = math::mul_vec(&math::transpose(w), &g_pc);

    let o = s.opacities[i];
    let inside = o > T::zero() && o < T::one();
    ParamGrads {
        mean: mean_grad,
        log_scale: g_log_scale,
        rotation,
        opacity_logit: if inside {
            g.opacity * o * (T::one() - o)
        } else {
            T::zero()
        },
    }
}
