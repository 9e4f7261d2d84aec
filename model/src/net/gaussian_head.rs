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
/// With `edge_shrink`: how far (in Gaussian cells) a farther neighbour makes a Gaussian an
/// edge's, about the reach of a footprint (on real pairs a footprint's sigma is about 1.5 cells).
pub const EDGE_RADIUS: usize = 2;
/// With `edge_shrink`: how many times farther that neighbour is (10%: a depth step, not a
/// slanted surface's change over two cells).
pub const EDGE_RATIO: f64 = 1.1;

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
    /// `edge_shrink` where it applies (with SGM's hints, as `snap`): the scale factor of
    /// the Gaussians on a foreground edge.
    pub edge_shrink: Option<f32>,
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
        let log_scales = match x.edge_shrink {
            Some(factor) => {
                let shrink =
                    (on_foreground_edge(&depth_map)?.reshape((v, 1, p))? * f64::from(factor).ln())?;
                log_scales.broadcast_add(&shrink)?
            }
            None => log_scales,
        };
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

/// 1 where a Gaussian of `depth` `(V, 1, Hg, Wg)` has a neighbour within [`EDGE_RADIUS`]
/// cells over [`EDGE_RATIO`] times farther (it lies on a foreground edge), else 0; same
/// shape. The border repeats the edge cells, so it makes no edge of its own.
fn on_foreground_edge(depth: &Tensor) -> Result<Tensor> {
    let r = EDGE_RADIUS;
    let padded = depth.pad_with_same(2, r, r)?.pad_with_same(3, r, r)?;
    let farthest = padded.max_pool2d_with_stride(2 * r + 1, 1)?;
    farthest.gt(&(depth * EDGE_RATIO)?)?.to_dtype(depth.dtype())
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The edge mask of one `h x w` depth map given row by row.
    fn edges(depth: Vec<f32>, h: usize, w: usize) -> Vec<f32> {
        let t = Tensor::from_vec(depth, (1, 1, h, w), &Device::Cpu).unwrap();
        let mask = on_foreground_edge(&t).unwrap();
        assert_eq!(mask.dims4().unwrap(), (1, 1, h, w));
        mask.flatten_all().unwrap().to_vec1().unwrap()
    }

    #[test]
    fn only_the_near_side_of_a_depth_step_within_reach_is_an_edge() {
        // Columns 0..4 a near surface, 4..10 one five times farther, at every scale of depth:
        // near 0, street-like and very far (the test is a ratio, so all agree).
        for near in [1e-6f32, 2.0, 1e6] {
            let row: Vec<f32> = (0..10)
                .map(|x| if x < 4 { near } else { 5.0 * near })
                .collect();
            let mask = edges(row.repeat(3), 3, 10);
            for y in 0..3 {
                let got = &mask[y * 10..(y + 1) * 10];
                // Columns 2 and 3 see the far side within EDGE_RADIUS = 2 cells; 0 and 1 do
                // not; the far side never does.
                assert_eq!(
                    got,
                    &[0., 0., 1., 1., 0., 0., 0., 0., 0., 0.],
                    "near {near}"
                );
            }
        }
    }

    #[test]
    fn a_gentle_slope_and_a_flat_map_have_no_edge() {
        // 4% farther per cell: 8% over the reach, under EDGE_RATIO's 10%.
        let slope: Vec<f32> = (0..8).map(|x| 3.0 * 1.04f32.powi(x)).collect();
        assert!(edges(slope.repeat(2), 2, 8).iter().all(|&m| m == 0.0));
        assert!(edges(vec![7.0; 12], 3, 4).iter().all(|&m| m == 0.0));
    }
}
