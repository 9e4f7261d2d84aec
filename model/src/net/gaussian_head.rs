//! The per-pixel Gaussian heads (paper section 3.2, "Gaussian parameter prediction"): the
//! centre is the back-projected depth plus a learned 3D offset, carried into the bin's frame
//! by the view's pose; opacity comes from the softmax matching confidence through two
//! convolutions (the sigmoid is the renderer's, on the logit); scale, rotation, SH degree-0
//! colour and a sigmoid confidence come from a shared convolutional trunk, which also
//! refines the depth head's estimate (a bounded residual in normalised inverse depth): two
//! 3x3 convolutions at the Gaussians' resolution and a 1x1 output, kept narrow since that
//! resolution is where the network spends most of its time.

use candle_core::{Device, Module, Result, Tensor};
use candle_nn::VarBuilder;

use crate::ops::Conv;
use renderer::Camera;

use super::blocks::{conv, ConvRelu};
use super::depth_head::metric_depth;
use super::geometry::{camera_to_world, orientation_matrix, rays};
use super::guidance::SnapTargets;
use super::Config;
use crate::ops::{upsample_bilinear, SplatTensors};

/// Output channels of the trunk: depth residual 1, offset 3, log-scale 3, rotation 4,
/// colour 3, confidence 1.
const TRUNK_OUT: usize = 15;
/// Largest change of normalised inverse depth the refinement makes.
const MAX_REFINE: f64 = 0.1;
/// Largest offset from the depth ray, in pixel footprints at the Gaussian's depth.
const MAX_OFFSET: f64 = 2.0;
/// Largest change of log-scale from one pixel footprint.
const MAX_LOG_SCALE: f64 = 2.0;
/// Largest change of colour from the image's.
const MAX_COLOR_SHIFT: f64 = 0.5;
/// What the heads read, all at the Gaussians' resolution `(V, k, Hg, Wg)` except the softmax.
pub struct HeadInputs<'a> {
    /// Per-pixel context (image, upsampled features), `(V, k, Hg, Wg)`.
    pub context: &'a Tensor,
    /// Image at the Gaussians' pixels, `(V, 3, Hg, Wg)`, in `[0, 1]`.
    pub image: &'a Tensor,
    /// The depth head's normalised inverse depth, upsampled, `(V, 1, Hg, Wg)`.
    pub coarse: &'a Tensor,
    /// The cost volume's softmax at 1/4 resolution, `(V, D, h, w)`.
    pub probabilities: &'a Tensor,
    /// The views' cameras (bin frame).
    pub cameras: &'a [Camera],
    /// The network's settings: their `near..far` turn the inverse depth into metres (the
    /// range the candidates spanned, which `auto_depth_range` may have fitted to the pair).
    pub net: &'a Config,
    /// With `sgm_snap` and hints: SGM's depth for the Gaussians it matched, which replaces
    /// the refined depth there.
    pub snap: Option<&'a SnapTargets>,
}

/// What the heads predict.
pub struct HeadOutput {
    /// One Gaussian per pixel of every view, `V Hg Wg` rows, view-major.
    pub splats: SplatTensors,
    /// Refined metric depth, `(V, 1, Hg, Wg)`.
    pub depth: Tensor,
}

/// The Gaussian heads.
#[derive(Clone, Debug)]
pub struct GaussianHead {
    spatial: Vec<ConvRelu>,
    out: Conv,
    opacity_hidden: ConvRelu,
    opacity_out: Conv,
    stride: usize,
}

impl GaussianHead {
    /// `context` channels of per-pixel context.
    pub fn new(vb: VarBuilder, cfg: &Config, context: usize) -> Result<Self> {
        let c = cfg.head_channels;
        Ok(Self {
            spatial: vec![
                ConvRelu::new(vb.pp("trunk0"), context + 1, c, 1)?,
                ConvRelu::new(vb.pp("trunk1"), c, c, 1)?,
            ],
            out: conv(vb.pp("out"), c, TRUNK_OUT, 1, 1)?,
            opacity_hidden: ConvRelu::new(vb.pp("opacity0"), cfg.candidates, 16, 1)?,
            opacity_out: conv(vb.pp("opacity1"), 16, 1, 3, 1)?,
            stride: cfg.gaussian_stride,
        })
    }

    /// The Gaussians and the refined depth.
    pub fn forward(&self, x: &HeadInputs) -> Result<HeadOutput> {
        let (v, _, hg, wg) = x.coarse.dims4()?;
        let p = hg * wg;
        let device = x.coarse.device();
        let t = super::blocks::chain(&self.spatial, &Tensor::cat(&[x.context, x.coarse], 1)?)?;
        let t = self.out.forward(&t)?;
        let refine = (t.narrow(1, 0, 1)?.tanh()? * MAX_REFINE)?;
        let inverse = (x.coarse + refine)?.clamp(0f32, 1f32)?;
        let inverse = match x.snap {
            Some(snap) => snap.mask.where_cond(&snap.inverse, &inverse)?,
            None => inverse,
        };
        let depth_map = metric_depth(&inverse, x.net)?;
        let t = t.reshape((v, TRUNK_OUT, p))?;
        let part = |from: usize, n: usize| t.narrow(1, from + 1, n);

        let depth = depth_map.reshape((v, 1, p))?;
        let inv_fx = per_view(x.cameras, device, |c| self.stride as f32 / c.intrinsics.fx)?;
        let footprint = depth.broadcast_mul(&inv_fx)?; // (V, 1, P) metres per Gaussian pixel
        let ray_grid: Vec<Tensor> = x
            .cameras
            .iter()
            .map(|c| rays(c, self.stride, hg, wg, device))
            .collect::<Result<_>>()?;
        let offset = (part(0, 3)?.tanh()? * MAX_OFFSET)?.broadcast_mul(&footprint)?;
        let local = (Tensor::stack(&ray_grid, 0)?.broadcast_mul(&depth)? + offset)?;
        let (rot, pos) = poses(x.cameras, device)?;
        let means = rot.matmul(&local)?.broadcast_add(&pos)?;

        let log_scales = footprint
            .log()?
            .broadcast_add(&(part(3, 3)?.tanh()? * MAX_LOG_SCALE)?)?;
        let identity = Tensor::new(&[1f32, 0., 0., 0.], device)?.reshape((1, 4, 1))?;
        let local_rot = part(6, 4)?.broadcast_add(&identity)?;
        let rotations = orientations(x.cameras, device)?.matmul(&local_rot)?;
        let image = x.image.reshape((v, 3, p))?;
        let colors = (image + (part(10, 3)?.tanh()? * MAX_COLOR_SHIFT)?)?;
        let confidences = candle_nn::ops::sigmoid(&part(13, 1)?)?;

        let opacity = self
            .opacity_out
            .forward(&self.opacity_hidden.forward(x.probabilities)?)?;
        let opacity_logits = upsample_bilinear(&opacity, hg, wg)?.reshape((v, 1, p))?;

        let rows = |t: Tensor| -> Result<Tensor> {
            let k = t.dim(1)?;
            t.transpose(1, 2)?.reshape((v * p, k))
        };
        Ok(HeadOutput {
            splats: SplatTensors {
                means: rows(means)?,
                log_scales: rows(log_scales)?,
                rotations: rows(rotations)?,
                opacity_logits: rows(opacity_logits)?,
                colors: rows(colors)?,
                confidences: rows(confidences)?,
            },
            depth: depth_map,
        })
    }
}

/// One value per view as `(V, 1, 1)`.
fn per_view(cameras: &[Camera], device: &Device, f: impl Fn(&Camera) -> f32) -> Result<Tensor> {
    let values: Vec<f32> = cameras.iter().map(f).collect();
    Tensor::from_vec(values, (cameras.len(), 1, 1), device)
}

/// Camera-to-world rotations `(V, 3, 3)` and camera centres `(V, 3, 1)`.
fn poses(cameras: &[Camera], device: &Device) -> Result<(Tensor, Tensor)> {
    let mut rot = Vec::with_capacity(9 * cameras.len());
    let mut pos = Vec::with_capacity(3 * cameras.len());
    for c in cameras {
        let m = camera_to_world(c);
        for r in 0..3 {
            rot.extend((0..3).map(|k| m.col(k)[r] as f32));
        }
        pos.extend(c.position.to_array());
    }
    let n = cameras.len();
    Ok((
        Tensor::from_vec(rot, (n, 3, 3), device)?,
        Tensor::from_vec(pos, (n, 3, 1), device)?,
    ))
}

/// The views' quaternion left-multiplication matrices `(V, 4, 4)`.
fn orientations(cameras: &[Camera], device: &Device) -> Result<Tensor> {
    let data: Vec<f32> = cameras
        .iter()
        .flat_map(|c| orientation_matrix(c).into_iter().flatten())
        .collect();
    Tensor::from_vec(data, (cameras.len(), 4, 4), device)
}
