//! StereoSplat+'s progressive pass (paper section 3.3), exactly one round per bin:
//!
//! 1. G_base: the bin map from the real input pairs, both branches as the preset has them
//!    ([`LearnedReconstructor::reconstruct_tensors`]).
//! 2. Pseudo stereo pairs at the poses ahead ([`pseudo_poses`]), rendered from G_base by the
//!    renderer's one entry point ([`renderer::RenderWith`]: wgpu on a hardware GPU, the CPU
//!    reference otherwise).
//! 3. Both views of each pseudo pair through the one-step enhancer (`model::enhance`), the
//!    bin's first left image as reference; with the `enhancer` setting off the raw renders
//!    go on (the paper's ablation row).
//! 4. The pseudo pairs through the cost-volume branch, appended after the real pairs' own
//!    prediction (G_plus's new part).
//! 5. Confidence-guided fusion per Gaussian ([`fusion`]): G_base whole, plus the pseudo
//!    pairs' Gaussians no earlier view explains, weighted by their confidence.
//!
//! The volume branch does not run again on the pseudo views: its top-k voxels would repeat
//! G_base's, and it would double the pass's cost. With the cost-volume branch's output off
//! (the Branch_3D row) the pass adds nothing: G_base is the map.

pub mod fusion;
pub mod pseudo_poses;

use std::time::Instant;

use candle_core::{Device, Tensor};
use renderer::{Camera, GaussianSet, Raster, RenderOutput, RenderSettings, RenderWith};

use crate::enhance::Enhancer;
use crate::net::{images_and_cameras, pair_fusion_flags, to_set, LearnedReconstructor, Prediction};
use crate::reconstruct::{ModelSplit, ReconstructError, Reconstructor, StereoView};
use pseudo_poses::{pseudo_pairs, PseudoPair};

/// Where the time of the last pass went, and what it added.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ProgressiveReport {
    /// Milliseconds per stage.
    pub split: ModelSplit,
    /// Pseudo stereo pairs made.
    pub pseudo_pairs: usize,
    /// Gaussians of G_base.
    pub base_gaussians: usize,
    /// Gaussians the pseudo pairs added.
    pub added_gaussians: usize,
}

/// The learned reconstructor with the progressive pass around it.
pub struct ProgressiveReconstructor {
    inner: LearnedReconstructor,
    enhancer: Option<Enhancer>,
    render_with: RenderWith,
    raster: Option<Raster>,
    name: String,
    last: Option<ProgressiveReport>,
    /// Reconstructions so far (the preset's `progressive_every` picks the bins by it).
    bins: u64,
}

impl ProgressiveReconstructor {
    /// The pass around `inner` (its preset's `pseudo_poses` place the pseudo pairs), with
    /// `enhancer` on the pseudo views (`None`: raw renders), rendering as `render_with` says
    /// (the rasterizer is made on the thread of the first reconstruction).
    pub fn new(
        inner: LearnedReconstructor,
        enhancer: Option<Enhancer>,
        render_with: RenderWith,
    ) -> Self {
        let suffix = if enhancer.is_some() { "+" } else { "+raw" };
        let name = format!("{}{suffix}", inner.name());
        Self {
            inner,
            enhancer,
            render_with,
            raster: None,
            name,
            last: None,
            bins: 0,
        }
    }

    /// Time and counts of the last pass.
    pub fn last_report(&self) -> Option<ProgressiveReport> {
        self.last
    }

    /// The pass on `views`, pseudo pairs placed by `ahead` (see [`pseudo_pairs`]).
    fn run(
        &mut self,
        views: &[StereoView<'_>],
        ahead: &[Camera],
    ) -> Result<GaussianSet, ReconstructError> {
        let backend = |e: candle_core::Error| ReconstructError::Backend(e.to_string());
        self.last = None;
        let start = Instant::now();
        let device = self.inner.device();
        let (images, cameras) = images_and_cameras(views, &device)?;
        let base = self.inner.reconstruct_tensors(&images, &cameras)?;
        let cfg = self.inner.net().config().clone();
        let mut report = ProgressiveReport {
            split: ModelSplit {
                base_ms: ms(start),
                ..Default::default()
            },
            base_gaussians: base.set.len(),
            ..Default::default()
        };
        let real: Vec<(Camera, Camera)> = views
            .iter()
            .map(|v| (v.left_camera, v.right_camera))
            .collect();
        let every = cfg.progressive_every as u64;
        let due = every > 0 && self.bins.is_multiple_of(every);
        self.bins += 1;
        let pseudo = match due {
            true => pseudo_pairs(&real, ahead, &cfg.pseudo_poses),
            false => Vec::new(),
        };
        if pseudo.is_empty() || !base.cost_volume.cost_volume_output {
            self.last = Some(report);
            return Ok(base.set);
        }

        let start = Instant::now();
        let raster = self.raster.get_or_insert_with(|| self.render_with.raster());
        let settings = RenderSettings::default();
        let pseudo_cameras: Vec<Camera> = pseudo
            .iter()
            .flat_map(|p: &PseudoPair| [p.left, p.right])
            .collect();
        let renders = pseudo_cameras
            .iter()
            .map(|cam| raster.render(&base.set, cam, &settings))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| ReconstructError::Backend(format!("pseudo view render: {e}")))?;
        let rendered = render_tensor(&renders, &device).map_err(backend)?;
        report.split.pseudo_render_ms = ms(start);

        let start = Instant::now();
        let pseudo_images = match &self.enhancer {
            Some(enhancer) => {
                let reference = images
                    .narrow(0, 0, 1)
                    .and_then(|first| first.repeat((pseudo_cameras.len(), 1, 1, 1)))
                    .map_err(backend)?;
                let out = enhancer.forward(&rendered, &reference).map_err(backend)?;
                report.split.enhance_ms = ms(start);
                out
            }
            None => rendered
                .narrow(1, 0, 3)
                .and_then(|rgb| rgb.contiguous())
                .map_err(backend)?,
        };

        let start = Instant::now();
        let plus = self
            .inner
            .cost_volume_prediction(&pseudo_images, &pseudo_cameras)
            .map_err(backend)?;
        let base_rows = base.cost_volume.splats.means.dim(0).map_err(backend)?;
        let joined = Prediction::cat(&[base.cost_volume, plus]).map_err(backend)?;
        let all_cameras = [cameras, pseudo_cameras].concat();
        let rows = joined.splats.means.dim(0).map_err(backend)?;
        let margin = Some(cfg.pseudo_fusion_margin);
        let mut flags = pair_fusion_flags(&joined, &all_cameras, &cfg, margin)
            .map_err(backend)?
            .unwrap_or_else(|| vec![true; rows]);
        flags[..base_rows].fill(false);
        let added =
            to_set(&joined.splats, Some(&flags), cfg.opacity_floor, usize::MAX).map_err(backend)?;
        report.split.plus_ms = ms(start);
        let start = Instant::now();
        let fused = fusion::fuse(
            &base.set,
            &added,
            &fusion::FuseSettings {
                floor: cfg.opacity_floor,
                budget: cfg.max_gaussians,
                confidence_power: cfg.pseudo_confidence_power,
            },
        );
        report.split.fuse_ms = ms(start);
        report.pseudo_pairs = pseudo.len();
        report.added_gaussians = fused.len() - report.base_gaussians;
        self.last = Some(report);
        Ok(fused)
    }
}

impl Reconstructor for ProgressiveReconstructor {
    fn name(&self) -> &str {
        &self.name
    }

    fn reconstruct(&mut self, views: &[StereoView<'_>]) -> Result<GaussianSet, ReconstructError> {
        self.run(views, &[])
    }

    fn reconstruct_ahead(
        &mut self,
        views: &[StereoView<'_>],
        ahead: &[Camera],
    ) -> Result<GaussianSet, ReconstructError> {
        self.run(views, ahead)
    }

    fn last_split(&self) -> Option<ModelSplit> {
        self.last.map(|r| r.split)
    }

    fn last_depth_range(&self) -> Option<(f32, f32)> {
        self.inner.last_depth_range()
    }
}

fn ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// Renders as the enhancer's input, `(N, 5, H, W)`: RGB, alpha, confidence, each clamped to
/// `[0, 1]` (non-finite values become 0).
pub fn render_tensor(renders: &[RenderOutput], device: &Device) -> candle_core::Result<Tensor> {
    let unit = |v: f32| {
        if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let views = renders
        .iter()
        .map(|r| {
            let (h, w) = (r.height as usize, r.width as usize);
            let rgb = Tensor::from_iter(r.rgb.iter().map(|&v| unit(v)), device)?
                .reshape((h, w, 3))?
                .permute((2, 0, 1))?;
            let plane = |v: &[f32]| {
                Tensor::from_iter(v.iter().map(|&x| unit(x)), device)?.reshape((1, h, w))
            };
            Tensor::cat(&[&rgb, &plane(&r.alpha)?, &plane(&r.confidence)?], 0)
        })
        .collect::<candle_core::Result<Vec<_>>>()?;
    Tensor::stack(&views, 0)
}
