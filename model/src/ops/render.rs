//! The renderer's CPU rasterizer as a candle op: Gaussians in, images out, and the
//! rasterizer's backward pass as the op's backward, so losses on rendered colour, depth,
//! alpha and confidence reach the network that predicted the Gaussians.
//!
//! **Parameters** are one `(G, PARAMS)` tensor per scene (candle custom ops take at most three
//! tensors), columns in this order (the `COL_*` constants):
//! mean `x y z` (metres, the camera's world frame), log-scale `x y z` (natural log of the
//! standard deviations, metres), rotation quaternion `w x y z` (raw: any norm, normalised by
//! the rasterizer, zero = identity), opacity logit (opacity = sigmoid), colour `r g b`
//! (linear, SH degree 0), confidence. [`SplatTensors::pack`] builds it from separate
//! tensors, so gradients flow back to each part.
//!
//! **Output** is `(OUT_CHANNELS, H, W)`: `r g b` (with the settings' background), depth,
//! alpha, confidence (the `CH_*` constants). Depth is the alpha-normalised expected depth
//! (camera z; 0 where alpha is below `renderer::output::MIN_DEPTH_ALPHA`), the depth that
//! evaluation scores against LiDAR; multiply by alpha for the raw expected depth.
//!
//! The camera and settings are fixed (not differentiated). Gradients are those of
//! `renderer::cpu::backward`: exact derivatives of the forward pass away from its few
//! discontinuities (tile edges, the 1/255 skip, the 0.99 alpha clamp, early termination). An
//! opacity that rounds to exactly 0 or 1 (a logit beyond about +-17 in `f32`) gets no
//! gradient, as in the rasterizer.

use std::any::Any;
use std::sync::Mutex;

use candle_core::{CpuStorage, CustomOp1, CustomOp2, DType, Device, Layout, Result, Shape, Tensor};
use renderer::cpu::{backward, ForwardPass, OutputGrads};
use renderer::gaussians::SplatsOwned;
use renderer::{Camera, GaussianSet, RenderSettings};

use super::cpu::{float_dtype, float_kernel, slice, Float, OpError};

/// Columns per Gaussian in the packed parameter tensor.
pub const PARAMS: usize = 15;
/// First column of the mean (x, y, z).
pub const COL_MEAN: usize = 0;
/// First column of the log-scale (x, y, z).
pub const COL_LOG_SCALE: usize = 3;
/// First column of the quaternion (w, x, y, z).
pub const COL_ROTATION: usize = 6;
/// Column of the opacity logit.
pub const COL_OPACITY_LOGIT: usize = 10;
/// First column of the colour (r, g, b).
pub const COL_COLOR: usize = 11;
/// Column of the confidence.
pub const COL_CONFIDENCE: usize = 14;

/// Output channels of [`render`].
pub const OUT_CHANNELS: usize = 6;
/// Output channel: red.
pub const CH_R: usize = 0;
/// Output channel: green.
pub const CH_G: usize = 1;
/// Output channel: blue.
pub const CH_B: usize = 2;
/// Output channel: alpha-normalised expected depth.
pub const CH_DEPTH: usize = 3;
/// Output channel: accumulated opacity.
pub const CH_ALPHA: usize = 4;
/// Output channel: composited confidence.
pub const CH_CONFIDENCE: usize = 5;

/// A Gaussian set as separate `(G, k)` tensors, the form network heads produce; [`Self::pack`]
/// joins them into the `(G, PARAMS)` tensor [`render`] takes.
#[derive(Clone, Debug)]
pub struct SplatTensors {
    /// `(G, 3)` centres.
    pub means: Tensor,
    /// `(G, 3)` log standard deviations.
    pub log_scales: Tensor,
    /// `(G, 4)` quaternions `w x y z`, any norm.
    pub rotations: Tensor,
    /// `(G, 1)` opacity logits.
    pub opacity_logits: Tensor,
    /// `(G, 3)` linear RGB.
    pub colors: Tensor,
    /// `(G, 1)` confidences.
    pub confidences: Tensor,
}

impl SplatTensors {
    /// The packed `(G, PARAMS)` tensor (a concatenation, so differentiable in every part).
    pub fn pack(&self) -> Result<Tensor> {
        Tensor::cat(
            &[
                &self.means,
                &self.log_scales,
                &self.rotations,
                &self.opacity_logits,
                &self.colors,
                &self.confidences,
            ],
            1,
        )
    }

    /// The Gaussians of `parts` in order as one set (the cost-volume branch's and the volume
    /// branch's, or several views' predictions): a concatenation, differentiable in every part.
    pub fn cat(parts: &[&SplatTensors]) -> Result<Self> {
        let cat = |f: fn(&SplatTensors) -> &Tensor| {
            Tensor::cat(&parts.iter().map(|p| f(p)).collect::<Vec<_>>(), 0)
        };
        Ok(Self {
            means: cat(|p| &p.means)?,
            log_scales: cat(|p| &p.log_scales)?,
            rotations: cat(|p| &p.rotations)?,
            opacity_logits: cat(|p| &p.opacity_logits)?,
            colors: cat(|p| &p.colors)?,
            confidences: cat(|p| &p.confidences)?,
        })
    }

    /// The tensors of a renderer Gaussian set (opacities become logits through
    /// `renderer::ply::opacity_logit`, which keeps 0 and 1 finite), for feeding existing maps
    /// and test scenes to [`render`].
    pub fn from_set(set: &GaussianSet, dtype: DType, device: &Device) -> Result<Self> {
        set.check_lengths().map_err(candle_core::Error::wrap)?;
        let g = set.len();
        let t = |v: Vec<f32>, k: usize| Tensor::from_vec(v, (g, k), device)?.to_dtype(dtype);
        let flat = |v: &[glam::Vec3]| v.iter().flat_map(|v| v.to_array()).collect();
        Ok(Self {
            means: t(flat(&set.means), 3)?,
            log_scales: t(flat(&set.log_scales), 3)?,
            rotations: t(
                set.rotations
                    .iter()
                    .flat_map(|q| [q.w, q.x, q.y, q.z])
                    .collect(),
                4,
            )?,
            opacity_logits: Tensor::from_vec(
                set.opacities
                    .iter()
                    .map(|&o| renderer::ply::opacity_logit(o))
                    .collect(),
                (g, 1),
                device,
            )?
            .to_dtype(dtype)?,
            colors: t(flat(&set.colors), 3)?,
            confidences: t(set.confidences.clone(), 1)?,
        })
    }
}

/// Renders the packed Gaussians `splats` `(G, PARAMS)` through `camera` with the CPU
/// rasterizer, giving `(OUT_CHANNELS, H, W)` (see the module doc for both layouts).
/// Differentiable with respect to `splats`; `f32` or `f64`. Splats on another device are
/// rasterized on the CPU and the images (and gradients) copied back (`crate::compute`).
pub fn render(splats: &Tensor, camera: &Camera, settings: &RenderSettings) -> Result<Tensor> {
    let (_, cols) = splats.dims2()?;
    if cols != PARAMS {
        return Err(OpError::shape(
            Render::NAME,
            format!("splats {:?} must be (G, {PARAMS})", splats.dims()),
        ));
    }
    let op = Render {
        camera: *camera,
        settings: *settings,
        forward: Mutex::new(None),
    };
    // `to_device` is a no-op for tensors already there.
    splats
        .to_device(&Device::Cpu)?
        .contiguous()?
        .apply_op1(op)?
        .to_device(splats.device())
}

/// The op: camera and settings, and the forward pass kept for the backward pass (a
/// `ForwardPass<f32>` or `ForwardPass<f64>`, taken by the first backward; a second backward
/// recomputes it).
struct Render {
    camera: Camera,
    settings: RenderSettings,
    forward: Mutex<Option<Box<dyn Any + Send>>>,
}

impl Render {
    const NAME: &'static str = "render";

    /// Unpacks `(G, PARAMS)` rows into the rasterizer's arrays.
    fn splats<T: Float>(params: &[T]) -> SplatsOwned<T> {
        let rows = params.chunks_exact(PARAMS);
        let vec3 = |c: usize| rows.clone().map(|r| [r[c], r[c + 1], r[c + 2]]).collect();
        let r = COL_ROTATION;
        let sigmoid = |x: T| T::one() / (T::one() + (-x).exp());
        SplatsOwned {
            means: vec3(COL_MEAN),
            log_scales: vec3(COL_LOG_SCALE),
            rotations: rows
                .clone()
                .map(|p| [p[r + 1], p[r + 2], p[r + 3], p[r]])
                .collect(),
            opacities: rows
                .clone()
                .map(|p| sigmoid(p[COL_OPACITY_LOGIT]))
                .collect(),
            colors: vec3(COL_COLOR),
            confidences: rows.map(|p| p[COL_CONFIDENCE]).collect(),
        }
    }

    fn forward_pass<T: Float>(&self, params: &[T]) -> ForwardPass<T> {
        let splats = Self::splats(params);
        let cam = self.camera.params::<T>();
        renderer::cpu::render(&splats.view(), &cam, &self.settings)
    }

    fn run<T: Float>(&self, params: &[T]) -> Vec<T> {
        let fwd = self.forward_pass(params);
        let o = &fwd.output;
        let mut out = Vec::with_capacity(OUT_CHANNELS * o.pixels());
        for k in 0..3 {
            out.extend(o.rgb.iter().skip(k).step_by(3));
        }
        out.extend(&o.depth);
        out.extend(&o.alpha);
        out.extend(&o.confidence);
        *self.forward.lock().unwrap_or_else(|e| e.into_inner()) = Some(Box::new(fwd));
        out
    }

    /// `d loss / d params` `(G, PARAMS)` from `d loss / d output` `(OUT_CHANNELS, H, W)`.
    fn grad<T: Float>(&self, params: &[T], grad: &[T]) -> Vec<T> {
        let cached = self
            .forward
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
            .and_then(|f| f.downcast::<ForwardPass<T>>().ok());
        let fwd = cached.map_or_else(|| self.forward_pass(params), |f| *f);
        let splats = Self::splats(params);
        let plane = |c: usize| &grad[c * fwd.output.pixels()..(c + 1) * fwd.output.pixels()];
        let rgb: Vec<T> = (0..fwd.output.pixels())
            .flat_map(|i| [CH_R, CH_G, CH_B].map(|c| plane(c)[i]))
            .collect();
        let out_grads = OutputGrads {
            rgb: Some(&rgb),
            depth: Some(plane(CH_DEPTH)),
            depth_raw: None,
            alpha: Some(plane(CH_ALPHA)),
            confidence: Some(plane(CH_CONFIDENCE)),
        };
        let cam = self.camera.params::<T>();
        let g = backward(&splats.view(), &cam, &self.settings, &fwd, &out_grads);
        let mut out = vec![T::zero(); params.len()];
        for (i, row) in out.chunks_exact_mut(PARAMS).enumerate() {
            let [qx, qy, qz, qw] = g.rotations[i];
            row[COL_MEAN..COL_MEAN + 3].copy_from_slice(&g.means[i]);
            row[COL_LOG_SCALE..COL_LOG_SCALE + 3].copy_from_slice(&g.log_scales[i]);
            row[COL_ROTATION..COL_ROTATION + 4].copy_from_slice(&[qw, qx, qy, qz]);
            row[COL_OPACITY_LOGIT] = g.opacity_logits[i];
            row[COL_COLOR..COL_COLOR + 3].copy_from_slice(&g.colors[i]);
            row[COL_CONFIDENCE] = g.confidences[i];
        }
        out
    }
}

impl CustomOp1 for Render {
    fn name(&self) -> &'static str {
        Self::NAME
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let dtype = float_dtype(Self::NAME, &[s])?;
        let out = float_kernel!(dtype, T => self.run(slice::<T>(Self::NAME, s, l)?));
        let k = &self.camera.intrinsics;
        let shape = (OUT_CHANNELS, k.height as usize, k.width as usize);
        Ok((out, Shape::from(shape)))
    }

    fn bwd(&self, arg: &Tensor, _res: &Tensor, grad: &Tensor) -> Result<Option<Tensor>> {
        let grad = grad.contiguous()?;
        Ok(Some(arg.apply_op2_no_bwd(&grad, &RenderGrad(self))?))
    }
}

/// The backward pass as an op on `(params, d output)`, so it runs on the tensors' storage.
struct RenderGrad<'a>(&'a Render);

impl CustomOp2 for RenderGrad<'_> {
    fn name(&self) -> &'static str {
        "render-grad"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let dtype = float_dtype(self.name(), &[s1, s2])?;
        let out = float_kernel!(dtype, T => self.0.grad(
            slice::<T>(self.name(), s1, l1)?,
            slice::<T>(self.name(), s2, l2)?,
        ));
        Ok((out, l1.shape().clone()))
    }
}
