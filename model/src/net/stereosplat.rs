//! The whole network: views in, per-view depth and per-pixel Gaussians out of the
//! cost-volume branch, then (when `volume_branch`) the 3D-volume branch's Gaussians from the
//! triplane the cost-volume Gaussians and the views' features fill; the output set is
//! G = G_cv ∪ G_vol (only G_vol without `cost_volume_branch`: the paper's Branch_3D row).

use std::sync::Arc;

use candle_core::{Device, Module, Result, Tensor};
use candle_nn::VarBuilder;

use crate::ops::Conv;
use renderer::Camera;

use super::blocks::conv;
use super::census_volume::census_volume;
use super::cost_volume::{candidate_depths, cost_volume};
use super::depth_head::{peak, DepthHead, ExtraCosts};
use super::depth_range::{fit_scene, rig_range, DepthRange};
use super::encoders::{Backbone, GeometryEncoder};
use super::gaussian_head::{GaussianHead, HeadInputs};
use super::guidance::{hint_volume, snap_targets, GuidanceStrength, SgmHints, GUIDANCE_WIDTH};
use super::hint_fill::fill_rows;
use super::transformer::MultiViewTransformer;
use super::volume::{BranchInputs, GaussiansPerBranch, VolumeBranch, VolumeOutput};
use super::Config;
use crate::ops::{upsample_bilinear, SplatTensors};

/// Image pixels per feature pixel of the cost volume (the paper's downscale factor).
pub const COST_STRIDE: usize = 4;

/// What one forward pass predicts (tensors share storage: a clone is cheap).
#[derive(Clone, Debug)]
pub struct Prediction {
    /// The cost-volume branch's Gaussians, `V * Hg * Wg` rows, view-major; nothing pruned
    /// (training needs all). Computed even when the branch's output is off, since their
    /// positions and features guide the volume branch; [`Prediction::output`] is the set.
    pub splats: SplatTensors,
    /// Estimated metric depth per view at the Gaussians' resolution, `(V, 1, Hg, Wg)`.
    pub depth: Tensor,
    /// The depth head's matching term: the correlation volume times its learned temperature,
    /// `(V, D, H/4, W/4)`, the logits matching alone puts on each candidate (what training's
    /// matching loss supervises, so the features must match, not only the priors guess).
    pub matching_logits: Tensor,
    /// Per-Gaussian features (the heads' context), `(V, k, Hg, Wg)`.
    pub features: Tensor,
    /// The views' features before normalisation, `(V, cost_channels, H/4, W/4)`: what the
    /// volume branch's cross-image attention samples.
    pub view_features: Tensor,
    /// The volume branch's Gaussians, occupancy logits and visible voxels; `None` when the
    /// branch is off.
    pub volume: Option<VolumeOutput>,
    /// Whether `splats` belong to the output (the preset's `cost_volume_branch`, or no
    /// volume branch to replace them).
    pub cost_volume_output: bool,
}

impl Prediction {
    /// Cost-volume predictions of disjoint view sets joined in order, as one prediction of
    /// all their views (the volume branch then runs once on the joined prediction, see
    /// [`StereoSplat::with_volume`]). Errors on a part that already holds volume output.
    pub fn cat(parts: &[Prediction]) -> Result<Self> {
        if parts.iter().any(|p| p.volume.is_some()) {
            candle_core::bail!("predictions with volume output cannot be joined");
        }
        let cat = |f: &dyn Fn(&Prediction) -> &Tensor| {
            Tensor::cat(&parts.iter().map(f).collect::<Vec<_>>(), 0)
        };
        Ok(Self {
            splats: SplatTensors::cat(&parts.iter().map(|p| &p.splats).collect::<Vec<_>>())?,
            depth: cat(&|p| &p.depth)?,
            matching_logits: cat(&|p| &p.matching_logits)?,
            features: cat(&|p| &p.features)?,
            view_features: cat(&|p| &p.view_features)?,
            volume: None,
            cost_volume_output: parts.iter().all(|p| p.cost_volume_output),
        })
    }

    /// The output Gaussians: the cost-volume branch's (when on) followed by the volume
    /// branch's (when on).
    pub fn output(&self) -> Result<SplatTensors> {
        match (&self.volume, self.cost_volume_output) {
            (None, _) => Ok(self.splats.clone()),
            (Some(v), false) => Ok(v.splats.clone()),
            (Some(v), true) => SplatTensors::cat(&[&self.splats, &v.splats]),
        }
    }

    /// Rows of the output each branch contributes (before floor and budget).
    pub fn counts(&self) -> GaussiansPerBranch {
        GaussiansPerBranch::of(
            self.cost_volume_output.then_some(&self.splats),
            self.volume.as_ref(),
        )
    }
}

/// The StereoSplat network: the cost-volume branch and, when the preset asks, the volume
/// branch (weights under `volume.*`; a preset without it reads no such weights, so files
/// trained before the branch existed load unchanged).
#[derive(Clone, Debug)]
pub struct StereoSplat {
    backbone: Backbone,
    geometry: GeometryEncoder,
    transformer: MultiViewTransformer,
    project: Conv,
    depth_head: DepthHead,
    gaussians: GaussianHead,
    volume: Option<VolumeBranch>,
    depths: Vec<f64>,
    /// With `sgm_guidance`: SGM's matches of the first pair ([`StereoSplat::fitted_to_scene`]).
    guidance: Option<Arc<SgmHints>>,
    cfg: Config,
    device: Device,
}

impl StereoSplat {
    /// The network of preset `cfg`, its variables under `vb`.
    pub fn new(vb: VarBuilder, cfg: &Config) -> Result<Self> {
        let context = 3 + cfg.cost_channels + cfg.backbone_channels / 2 + 1;
        if !cfg.cost_volume_branch && !cfg.volume_branch {
            candle_core::bail!("cost_volume_branch and volume_branch are both off: no output");
        }
        let volume = match cfg.volume_branch {
            true => Some(VolumeBranch::new(vb.pp("volume"), cfg, context)?),
            false => None,
        };
        Ok(Self {
            backbone: Backbone::new(vb.pp("backbone"), cfg)?,
            geometry: GeometryEncoder::new(vb.pp("geometry"), cfg)?,
            transformer: MultiViewTransformer::new(vb.pp("transformer"), cfg)?,
            project: conv(
                vb.pp("project"),
                cfg.view_channels(),
                cfg.cost_channels,
                1,
                1,
            )?,
            depth_head: DepthHead::new(vb.pp("depth_head"), cfg)?,
            gaussians: GaussianHead::new(vb.pp("gaussians"), cfg, context)?,
            volume,
            depths: candidate_depths(cfg),
            guidance: None,
            cfg: cfg.clone(),
            device: vb.device().clone(),
        })
    }

    /// The same network (sharing its weights) with its depth candidates over `range`
    /// instead of the preset's `near..far`: the candidates stay uniform in inverse depth, so
    /// the depth head reads them as before (`auto_depth_range`).
    pub fn with_depth_range(&self, range: DepthRange) -> Self {
        let mut net = self.clone();
        net.cfg.near = range.near;
        net.cfg.far = range.far;
        net.depths = candidate_depths(&net.cfg);
        net
    }

    /// The same network with its candidates over the range the rig of `cameras` calls for
    /// (`rig_disparity_fraction`, [`rig_range`]); itself when that is off or the rig unusable.
    pub fn for_rig(&self, cameras: &[Camera]) -> Self {
        match rig_range(cameras, &self.cfg) {
            Some(range) => self.with_depth_range(range),
            None => self.clone(),
        }
    }

    /// The same network fitted to the scene the first pair of `images` shows: its depth
    /// range with `auto_depth_range`, SGM's matches as hints with `sgm_guidance`, both from
    /// one SGM run ([`fit_scene`]) and both only on scenes whose fitted range passes
    /// `auto_depth_range_max_far` (near scenes, where SGM's disparities are large and its
    /// matches precise; on the streets the hints cost 0.5 dB); on near scenes without the
    /// volume branch with `volume_branch_far_only`. `None` when neither is on
    /// or SGM could not match the pair; the range is `None` where the preset's stays.
    pub fn fitted_to_scene(
        &self,
        images: &Tensor,
        cameras: &[Camera],
    ) -> Option<(Self, Option<DepthRange>)> {
        let cfg = &self.cfg;
        if !cfg.fits_scene() {
            return None;
        }
        let fit = fit_scene(images, cameras, cfg)?;
        let near_scene = fit.range.is_some();
        let range = fit.range.filter(|_| cfg.auto_depth_range);
        let mut net = match range {
            Some(range) => self.with_depth_range(range),
            None => self.clone(),
        };
        if cfg.sgm_guidance.is_some() && near_scene {
            let hints = match cfg.sgm_fill {
                true => fill_rows(fit.hints),
                false => fit.hints,
            };
            net.guidance = Some(Arc::new(hints));
        }
        if cfg.volume_branch_far_only && near_scene {
            net.volume = None;
        }
        Some((net, range))
    }

    /// The same network without SGM's hints: for the pairs after the one they were matched
    /// on, which run through the network alone (pair by pair).
    pub fn without_hints(&self) -> Self {
        let mut net = self.clone();
        net.guidance = None;
        net
    }

    /// The preset.
    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// The device its weights live on (`Config::device` when loaded through the project's
    /// loaders).
    pub fn device(&self) -> Device {
        self.device.clone()
    }

    /// `images` `(V, 3, H, W)` in `[0, 1]` (left and right of each pair, any order) with their
    /// `cameras` in the bin's frame, `V >= 1`: both branches as the preset switches them.
    pub fn forward(&self, images: &Tensor, cameras: &[Camera]) -> Result<Prediction> {
        let prediction = self.cost_volume(images, cameras)?;
        self.with_volume(prediction, cameras)
    }

    /// `prediction` of the cost-volume branch (of all of `cameras`' views) with the volume
    /// branch's output added when the preset has the branch; unchanged otherwise.
    pub fn with_volume(
        &self,
        mut prediction: Prediction,
        cameras: &[Camera],
    ) -> Result<Prediction> {
        if let Some(branch) = &self.volume {
            prediction.volume = Some(branch.forward(&BranchInputs {
                means: &prediction.splats.means,
                features: &prediction.features,
                view_features: &prediction.view_features,
                cameras,
                stride: COST_STRIDE,
            })?);
        }
        Ok(prediction)
    }

    /// The cost-volume branch alone (`volume: None`): what [`StereoSplat::forward`] runs
    /// first, and what pair-by-pair inference runs per pair.
    pub fn cost_volume(&self, images: &Tensor, cameras: &[Camera]) -> Result<Prediction> {
        let (v, _, height, width) = images.dims4()?;
        if v != cameras.len() || v == 0 {
            candle_core::bail!("{v} images but {} cameras", cameras.len());
        }
        let x = ((images * 2.0)? - 1.0)?;
        let bb = self.backbone.forward(&x)?;
        let (_, _, h, w) = bb.quarter.dims4()?;
        let mono = self.geometry.forward(&x, h, w)?;
        let attended = self.transformer.forward(&bb.quarter)?;
        let features = self
            .project
            .forward(&Tensor::cat(&[&mono, &attended], 1)?)?;
        // The plane sweep: the network's candidates on the 1/4 grid.
        let cost = cost_volume(
            &unit_features(&features)?,
            cameras,
            &self.depths,
            &self.cfg,
            COST_STRIDE,
        )?;
        let census_cost = self
            .cfg
            .census_matching
            .then(|| census_volume(images, cameras, &self.depths, &self.cfg, COST_STRIDE))
            .transpose()?;
        // Hints matched at another size than these images' do not belong to them.
        let hints = self.guidance.as_deref().filter(|h| h.width == width);
        let guidance = match (hints, self.cfg.sgm_guidance) {
            (Some(hints), Some(height)) => Some(hint_volume(
                hints,
                &self.depths,
                v,
                (h, w),
                COST_STRIDE,
                GuidanceStrength {
                    height,
                    width: GUIDANCE_WIDTH,
                },
                &self.device,
            )?),
            _ => None,
        };
        let extra = ExtraCosts {
            census: census_cost.as_ref(),
            guidance: guidance.as_ref(),
        };
        let coarse = self.depth_head.forward(&cost, &features, extra)?;

        let g = self.cfg.gaussian_stride;
        let (hg, wg) = (height.div_ceil(g), width.div_ceil(g));
        let up = |t: &Tensor| -> Result<Tensor> {
            let (_, _, th, tw) = t.dims4()?;
            if (th, tw) == (hg, wg) {
                Ok(t.clone())
            } else {
                upsample_bilinear(t, hg, wg)
            }
        };
        let snap = hints
            .filter(|_| self.cfg.sgm_snap)
            .map(|hints| snap_targets(hints, &self.cfg, v, (hg, wg), g, &self.device))
            .transpose()?;
        let image = every_nth_pixel(images, g)?;
        let confidence = up(&peak(&coarse.probabilities)?)?;
        let context = Tensor::cat(&[&image, &up(&features)?, &up(&bb.half)?, &confidence], 1)?;
        let heads = self.gaussians.forward(&HeadInputs {
            context: &context,
            image: &image,
            coarse: &up(&coarse.inverse)?,
            probabilities: &coarse.probabilities,
            cameras,
            net: &self.cfg,
            snap: snap.as_ref(),
        })?;
        Ok(Prediction {
            splats: heads.splats,
            depth: heads.depth,
            matching_logits: coarse.matching,
            features: context,
            view_features: features,
            volume: None,
            cost_volume_output: self.cfg.cost_volume_branch || self.volume.is_none(),
        })
    }
}

/// Features scaled to unit length per pixel: the volume holds cosine similarities, whose
/// scale the depth head's learned temperature sets (raw dot products of fresh features give
/// a flat softmax).
fn unit_features(features: &Tensor) -> Result<Tensor> {
    let norm = (features.sqr()?.sum_keepdim(1)? + 1e-6)?.sqrt()?;
    features.broadcast_div(&norm)
}

/// Pixels `(g i, g j)` of `(V, C, H, W)`: `(V, C, ceil(H/g), ceil(W/g))`, the pixels the
/// Gaussians sit on.
pub fn every_nth_pixel(x: &Tensor, g: usize) -> Result<Tensor> {
    if g == 1 {
        return Ok(x.clone());
    }
    let (_, _, h, w) = x.dims4()?;
    let pick = |n: usize| Tensor::arange_step(0u32, n as u32, g as u32, x.device());
    x.index_select(&pick(h)?, 2)?.index_select(&pick(w)?, 3)
}
