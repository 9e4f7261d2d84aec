//! The sinusoidal camera-pose code PE(T_i) of paper section 3.2.2: a view's camera-to-bin
//! pose as translation and SO(3) log map, each of the six numbers through M sines and
//! cosines, optionally the raw numbers too, zero-padded or cut to the plane channels. It
//! replaces OmniScene's learned per-camera embeddings, so any number of views and any pose
//! (pseudo views included) gets a code.
//!
//! The cameras the network gets are already in the bin frame (`x_cam = R (x_bin - c)`, see
//! `renderer::Camera`); the encoded pose is the camera-to-bin transform `T = [R^T | c]`: its
//! translation is the camera centre `c`, its rotation `R^T`. Computed in `f64` on the CPU
//! (poses are inputs, not learned).

use candle_core::{DType, Device, Result, Tensor};
use glam::{DMat3, DVec3};
use renderer::Camera;

use super::VolumeConfig;

/// Below this rotation angle (radians) the log and exp maps use their Taylor series.
const SMALL_ANGLE: f64 = 1e-6;

/// The SO(3) log map: the rotation vector `theta * axis` (`theta` in `[0, pi]`) of rotation
/// matrix `r`. Goes through the quaternion of `r` picked by its largest component (Shepperd's
/// method), so it stays accurate near the identity and near `pi`; at exactly `pi` the sign of
/// the axis is either (both are the same rotation).
pub fn so3_log(r: DMat3) -> DVec3 {
    let m = r.to_cols_array_2d(); // m[col][row]
    let e = |row: usize, col: usize| m[col][row];
    let trace = e(0, 0) + e(1, 1) + e(2, 2);
    // (w, x, y, z) up to a common positive factor, from whichever of w, x, y, z is largest.
    let q = if trace >= e(0, 0).max(e(1, 1)).max(e(2, 2)) {
        let s = (1.0 + trace).max(0.0).sqrt() * 2.0; // 4 w
        [
            0.25 * s,
            (e(2, 1) - e(1, 2)) / s,
            (e(0, 2) - e(2, 0)) / s,
            (e(1, 0) - e(0, 1)) / s,
        ]
    } else if e(0, 0) >= e(1, 1) && e(0, 0) >= e(2, 2) {
        let s = (1.0 + e(0, 0) - e(1, 1) - e(2, 2)).max(0.0).sqrt() * 2.0; // 4 x
        [
            (e(2, 1) - e(1, 2)) / s,
            0.25 * s,
            (e(0, 1) + e(1, 0)) / s,
            (e(0, 2) + e(2, 0)) / s,
        ]
    } else if e(1, 1) >= e(2, 2) {
        let s = (1.0 + e(1, 1) - e(0, 0) - e(2, 2)).max(0.0).sqrt() * 2.0; // 4 y
        [
            (e(0, 2) - e(2, 0)) / s,
            (e(0, 1) + e(1, 0)) / s,
            0.25 * s,
            (e(1, 2) + e(2, 1)) / s,
        ]
    } else {
        let s = (1.0 + e(2, 2) - e(0, 0) - e(1, 1)).max(0.0).sqrt() * 2.0; // 4 z
        [
            (e(1, 0) - e(0, 1)) / s,
            (e(0, 2) + e(2, 0)) / s,
            (e(1, 2) + e(2, 1)) / s,
            0.25 * s,
        ]
    };
    // w >= 0 picks the angle in [0, pi].
    let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
    let w = sign * q[0];
    let v = DVec3::new(q[1], q[2], q[3]) * sign;
    let norm = (w * w + v.length_squared()).sqrt();
    if norm.is_nan() || norm <= 0.0 {
        return DVec3::ZERO;
    }
    let (w, v) = (w / norm, v / norm);
    let s = v.length();
    let theta = 2.0 * s.atan2(w);
    if theta < SMALL_ANGLE {
        // theta / sin(theta / 2) = 2 (1 + theta^2 / 24 + ...), and w ~ 1.
        v * (2.0 / w)
    } else {
        v * (theta / s)
    }
}

/// The SO(3) exp map (Rodrigues): the rotation matrix of rotation vector `w`.
pub fn so3_exp(w: DVec3) -> DMat3 {
    let theta2 = w.length_squared();
    let theta = theta2.sqrt();
    let (a, b) = if theta < SMALL_ANGLE {
        (1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0)
    } else {
        (theta.sin() / theta, (1.0 - theta.cos()) / theta2)
    };
    let k = DMat3::from_cols(
        DVec3::new(0.0, w.z, -w.y),
        DVec3::new(-w.z, 0.0, w.x),
        DVec3::new(w.y, -w.x, 0.0),
    );
    DMat3::IDENTITY + k * a + k * k * b
}

/// PE(T_i) with the settings of a [`VolumeConfig`] and the output width D.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseEncoding {
    /// `omega_m = 2 pi b^(-(m-1)/(M-1))`, `m = 1..M` (`2 pi` alone when M = 1).
    frequencies: Vec<f64>,
    translation_scale: f64,
    rotation_scale: f64,
    raw: bool,
    dim: usize,
}

impl PoseEncoding {
    /// The code of `cfg` (frequencies, scales, raw-pose switch) padded or cut to `dim`.
    pub fn new(cfg: &VolumeConfig, dim: usize) -> Self {
        let m = cfg.pose_frequencies;
        let b = cfg.pose_base as f64;
        let frequencies = (0..m)
            .map(|i| {
                let e = if m > 1 {
                    i as f64 / (m - 1) as f64
                } else {
                    0.0
                };
                2.0 * std::f64::consts::PI * b.powf(-e)
            })
            .collect();
        Self {
            frequencies,
            translation_scale: cfg.pose_translation_scale as f64,
            rotation_scale: cfg.pose_rotation_scale as f64,
            raw: cfg.pose_raw,
            dim,
        }
    }

    /// The output width D.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The normalised pose `x = [t s_t, Log(R) s_r]` of a camera-to-bin rotation `rotation`
    /// and translation `translation`: the config's scales multiply (they are the paper's
    /// `1 / s_t` and `1 / s_r`).
    pub fn normalised(&self, rotation: DMat3, translation: DVec3) -> [f64; 6] {
        let t = translation * self.translation_scale;
        let r = so3_log(rotation) * self.rotation_scale;
        [t.x, t.y, t.z, r.x, r.y, r.z]
    }

    /// PE of a camera-to-bin pose: `pad_D([phi(x_1) .. phi(x_6), gamma x])` with
    /// `phi(x) = [sin(omega_1 x), cos(omega_1 x), .., sin(omega_M x), cos(omega_M x)]`.
    pub fn encode_pose(&self, rotation: DMat3, translation: DVec3) -> Vec<f64> {
        let x = self.normalised(rotation, translation);
        let mut code = Vec::with_capacity(6 * (2 * self.frequencies.len() + 1));
        for &xi in &x {
            for &w in &self.frequencies {
                code.push((w * xi).sin());
                code.push((w * xi).cos());
            }
        }
        if self.raw {
            code.extend(x);
        }
        code.resize(self.dim, 0.0);
        code
    }

    /// PE of a camera given in the bin frame (its camera-to-bin pose `[R^T | c]`).
    pub fn encode(&self, camera: &Camera) -> Vec<f64> {
        self.encode_pose(
            camera.rotation.as_dmat3().transpose(),
            camera.position.as_dvec3(),
        )
    }

    /// The codes of `cameras` as a constant `(V, D)` tensor of `dtype`.
    pub fn forward(&self, cameras: &[Camera], dtype: DType, device: &Device) -> Result<Tensor> {
        let data: Vec<f64> = cameras.iter().flat_map(|c| self.encode(c)).collect();
        Tensor::from_vec(data, (cameras.len(), self.dim), device)?.to_dtype(dtype)
    }
}
