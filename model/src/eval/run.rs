//! Runs the protocol over the bins of a sequence.

use std::path::PathBuf;
use std::time::Instant;

use candle_core::Tensor;
use renderer::{Camera, RenderOutput, RenderSettings};

use super::pictures::{self, ScoredRender};
use super::report::{BinReport, FrameScore, SkippedBin};
use super::unseen::{unseen_mask, unseen_psnr, InputView};
use crate::bins::{make_bins, Bin, BinConfig};
use crate::frame::{DepthMap, RgbImage, Side, StereoFrame};
use crate::kitti360::{Kitti360Error, Sequence};
use crate::lpips::Lpips;
use crate::metrics::{self, DepthFilter, MetricError};
use crate::reconstruct::{ReconstructError, Reconstructor, StereoView};
use renderer::Raster;

/// Settings of an evaluation run.
#[derive(Clone, Debug)]
pub struct EvalConfig {
    /// How bins are cut (8 m, one per start frame, as the paper).
    pub bins: BinConfig,
    /// Which LiDAR pixels count for the depth scores.
    pub depth: DepthFilter,
    /// Evaluate at most this many bins per sequence, spread evenly over it (`None`: all).
    pub max_bins: Option<usize>,
    /// How many bins (spread evenly over the evaluated ones) get pictures.
    pub picture_bins: usize,
    /// Where pictures go (`None`: no pictures).
    pub picture_dir: Option<PathBuf>,
    /// Background and clipping of the renders.
    pub render: RenderSettings,
    /// The LPIPS network every frame is also scored with, loaded once per evaluation
    /// (e.g. [`Lpips::load_default`]); `None` skips LPIPS, which is the slowest metric.
    pub lpips: Option<Lpips>,
    /// Input stereo pairs per bin: its first `input_pairs` frames (the paper's protocol is
    /// 1; more checks that quality does not fall as pairs are added). Capped at the bin's
    /// frame count.
    pub input_pairs: usize,
}

impl Default for EvalConfig {
    fn default() -> Self {
        Self {
            bins: BinConfig::default(),
            depth: DepthFilter::default(),
            max_bins: None,
            picture_bins: 3,
            picture_dir: None,
            render: RenderSettings::default(),
            lpips: None,
            input_pairs: 1,
        }
    }
}

/// Why an evaluation stopped (per-bin failures are skipped and counted instead).
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A frame or its LiDAR could not be read.
    #[error(transparent)]
    Data(#[from] Kitti360Error),
    /// The reconstructor failed.
    #[error(transparent)]
    Reconstruct(#[from] ReconstructError),
    /// A render failed (GPU lost, sizes).
    #[error("rendering failed: {0}")]
    Render(#[from] renderer::gpu::GpuError),
    /// A metric refused its inputs (sizes, non-finite values).
    #[error(transparent)]
    Metric(#[from] MetricError),
    /// LPIPS failed (an image too small for AlexNet, under about 31 pixels a side).
    #[error("LPIPS failed: {0}")]
    Lpips(#[from] candle_core::Error),
    /// Writing a picture failed.
    #[error("writing a picture failed: {0}")]
    Picture(String),
}

/// The bins `config` evaluates on `sequence`: all of them, or `max_bins` spread evenly.
pub fn select_bins(sequence: &Sequence, config: &EvalConfig) -> Vec<Bin> {
    let poses: Vec<_> = sequence.frames().iter().map(|f| f.left_to_world).collect();
    spread(make_bins(&poses, &config.bins), config.max_bins)
}

/// At most `n` of `items`, evenly spaced, first included.
fn spread<T: Copy>(items: Vec<T>, n: Option<usize>) -> Vec<T> {
    match n {
        Some(n) if n < items.len() => (0..n).map(|k| items[k * items.len() / n]).collect(),
        _ => items,
    }
}

/// Evaluates `reconstructor` on every selected bin of `sequence`. `progress` is called after
/// each bin with (bins done, bins in all). A bin whose frames fail to load or whose
/// reconstruction fails is skipped with its reason; a failing render or metric stops the
/// run (those are bugs, not bad data).
pub fn evaluate(
    sequence: &Sequence,
    reconstructor: &mut dyn Reconstructor,
    raster: &mut Raster,
    config: &EvalConfig,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(Vec<BinReport>, Vec<SkippedBin>), EvalError> {
    let bins = select_bins(sequence, config);
    let with_pictures: Vec<Bin> = spread(bins.clone(), Some(config.picture_bins));
    let mut reports = Vec::new();
    let mut skipped = Vec::new();
    for (k, bin) in bins.iter().enumerate() {
        let first = sequence.frames()[bin.first].index;
        let picture_dir = config
            .picture_dir
            .as_ref()
            .filter(|_| with_pictures.contains(bin));
        match evaluate_bin(
            sequence,
            reconstructor,
            raster,
            config,
            bin,
            picture_dir.is_some(),
        ) {
            Ok((report, renders)) => {
                if let Some(dir) = picture_dir {
                    pictures::write_bin(dir, sequence.name(), &report, &renders)
                        .map_err(|e| EvalError::Picture(e.to_string()))?;
                }
                reports.push(report);
            }
            Err(e @ (EvalError::Data(_) | EvalError::Reconstruct(_))) => skipped.push(SkippedBin {
                sequence: sequence.name().to_string(),
                first,
                reason: e.to_string(),
            }),
            Err(e) => return Err(e),
        }
        progress(k + 1, bins.len());
    }
    Ok((reports, skipped))
}

fn evaluate_bin(
    sequence: &Sequence,
    reconstructor: &mut dyn Reconstructor,
    raster: &mut Raster,
    config: &EvalConfig,
    bin: &Bin,
    keep_renders: bool,
) -> Result<(BinReport, Vec<ScoredRender>), EvalError> {
    let rig = sequence.rig();
    let poses = sequence.frames();
    let frames: Vec<StereoFrame> = bin
        .frames()
        .map(|i| sequence.load_frame(poses[i].index))
        .collect::<Result<_, _>>()?;
    let origin = frames[0].left_to_world;
    let camera = |f: &StereoFrame, side| rig.local_camera(origin, f.left_to_world, side);
    let inputs: Vec<StereoView> = frames
        .iter()
        .take(config.input_pairs.max(1))
        .map(|f| StereoView {
            left: &f.left,
            right: &f.right,
            left_camera: camera(f, Side::Left),
            right_camera: camera(f, Side::Right),
        })
        .collect();
    // The bin's later poses are known here: the progressive pass puts its pseudo views there.
    let ahead: Vec<Camera> = frames[inputs.len()..]
        .iter()
        .map(|f| camera(f, Side::Left))
        .collect();
    let start = Instant::now();
    let set = reconstructor.reconstruct_ahead(&inputs, &ahead)?;
    let reconstruct_ms = start.elapsed().as_secs_f64() * 1e3;

    // Exact depth of the input views, when the drive has it (generated drives).
    let input_depth: Option<Vec<(Camera, DepthMap)>> = inputs
        .iter()
        .zip(&frames)
        .flat_map(|(view, f)| {
            [
                (view.left_camera, f.index, Side::Left),
                (view.right_camera, f.index, Side::Right),
            ]
        })
        .map(|(cam, index, side)| Ok(sequence.exact_depth(index, side)?.map(|d| (cam, d))))
        .collect::<Result<Option<Vec<_>>, Kitti360Error>>()?;

    let mut scores = Vec::new();
    let mut renders = Vec::new();
    for (i, frame) in bin.frames().zip(&frames) {
        for side in [Side::Left, Side::Right] {
            let target = camera(frame, side);
            let render = raster.render(&set, &target, &config.render)?;
            let truth = match side {
                Side::Left => &frame.left,
                Side::Right => &frame.right,
            };
            let unseen = match (&input_depth, sequence.exact_depth(frame.index, side)?) {
                (Some(inputs), Some(depth)) => {
                    let views: Vec<InputView> = inputs
                        .iter()
                        .map(|(camera, depth)| InputView { camera, depth })
                        .collect();
                    Some(unseen_mask(&target, &depth, &views))
                }
                _ => None,
            };
            let lidar = sequence.lidar_depth(frame.index, side);
            let score = score_frame(
                FrameTarget {
                    frame: frame.index,
                    side,
                    role: bin.role(i),
                    truth,
                    unseen: unseen.as_deref(),
                },
                &render,
                lidar,
                config,
            )?;
            // Only the bins that get pictures keep their renders.
            if keep_renders {
                renders.push(ScoredRender {
                    score: score.clone(),
                    truth: truth.clone(),
                    render,
                });
            }
            scores.push(score);
        }
    }
    let report = BinReport {
        sequence: sequence.name().to_string(),
        first: poses[bin.first].index,
        centre: poses[bin.centre].index,
        last: poses[bin.last].index,
        gaussians: set.len(),
        reconstruct_ms,
        fitted_depth_range_m: reconstructor
            .last_depth_range()
            .map(|(near, far)| [near, far]),
        frames: scores,
    };
    Ok((report, renders))
}

/// The recorded frame a render is scored against.
#[derive(Clone, Copy, Debug)]
pub struct FrameTarget<'a> {
    /// The frame number in the sequence.
    pub frame: u32,
    /// Which camera.
    pub side: Side,
    /// First, centre or last frame of the bin, or none of them.
    pub role: Option<crate::bins::Role>,
    /// The recorded image.
    pub truth: &'a RgbImage,
    /// Per pixel, whether no input view saw its surface ([`unseen_mask`]); `None` without
    /// exact depth.
    pub unseen: Option<&'a [bool]>,
}

/// Scores one render against the recorded image and LiDAR with `config`'s metrics (also
/// used to score the node's fused map). Missing LiDAR (no file, an empty scan, no point
/// inside the depth range) leaves the depth scores empty rather than failing the bin.
pub fn score_frame(
    target: FrameTarget,
    render: &RenderOutput,
    lidar: Result<DepthMap, Kitti360Error>,
    config: &EvalConfig,
) -> Result<FrameScore, EvalError> {
    let truth = target.truth;
    let image = RgbImage {
        width: render.width,
        height: render.height,
        data: render.rgb.clone(),
    };
    let psnr = metrics::psnr(&image, truth)?;
    let ssim = metrics::ssim(&image, truth)?;
    let lpips = match &config.lpips {
        Some(net) => Some(lpips_distance(net, &image, truth)?),
        None => None,
    };
    let (unseen_psnr, unseen_pixels) = match target.unseen {
        Some(mask) => (
            unseen_psnr(&image, truth, mask)?,
            mask.iter().filter(|&&u| u).count(),
        ),
        None => (None, 0),
    };
    let depth = rendered_depth(render);
    let errors = match lidar {
        Ok(gt) => match metrics::depth_errors(&depth, &gt, &config.depth) {
            Ok(e) => Some(e),
            Err(MetricError::NoValidPixels) => None,
            Err(e) => return Err(e.into()),
        },
        Err(_) => None,
    };
    Ok(FrameScore {
        frame: target.frame,
        side: target.side,
        role: target.role,
        psnr,
        ssim,
        lpips,
        abs_rel: errors.as_ref().map(|e| e.abs_rel),
        sq_rel: errors.as_ref().map(|e| e.sq_rel),
        lidar_pixels: errors.as_ref().map_or(0, |e| e.valid),
        unseen_psnr,
        unseen_pixels,
    })
}

/// LPIPS between two images of the same size (checked by the metrics before).
fn lpips_distance(net: &Lpips, a: &RgbImage, b: &RgbImage) -> candle_core::Result<f64> {
    let d = net.forward(&to_tensor(net, a)?, &to_tensor(net, b)?)?;
    Ok(d.to_dtype(candle_core::DType::F64)?.to_vec1::<f64>()?[0])
}

/// An image as the `(1, 3, H, W)` tensor LPIPS takes, on the network's device.
fn to_tensor(net: &Lpips, image: &RgbImage) -> candle_core::Result<Tensor> {
    let (w, h) = (image.width as usize, image.height as usize);
    Tensor::from_slice(&image.data, (h, w, 3), net.device())?
        .permute((2, 0, 1))?
        .unsqueeze(0)?
        .to_dtype(net.dtype())
}

/// The render's alpha-normalised depth as a depth map (0 where nothing was drawn).
pub fn rendered_depth(render: &RenderOutput) -> DepthMap {
    DepthMap {
        width: render.width,
        height: render.height,
        data: render.depth.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64x48 image with a horizontal ramp in red and `blue` everywhere.
    fn ramp(blue: f32) -> RgbImage {
        let (w, h) = (64, 48);
        let data = (0..w * h)
            .flat_map(|i| [(i % w) as f32 / w as f32, 0.5, blue])
            .collect();
        RgbImage {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn lpips_is_zero_for_equal_images_and_matches_the_network_on_a_pair() {
        let net = Lpips::load_default().unwrap();
        let (a, b) = (ramp(0.2), ramp(0.8));
        assert_eq!(lpips_distance(&net, &a, &a).unwrap(), 0.0);
        let d = lpips_distance(&net, &a, &b).unwrap();
        // The same pair laid out by hand as (1, 3, H, W): channel planes, not interleaved.
        let planes = |img: &RgbImage| {
            let v: Vec<f32> = (0..3)
                .flat_map(|c| img.data.iter().skip(c).step_by(3).copied())
                .collect();
            Tensor::from_vec(v, (1, 3, 48, 64), &candle_core::Device::Cpu).unwrap()
        };
        let want = net.forward(&planes(&a), &planes(&b)).unwrap();
        let want = want.to_vec1::<f32>().unwrap()[0] as f64;
        assert!(d > 0.0 && (d - want).abs() < 1e-7, "{d} vs {want}");
    }
}
