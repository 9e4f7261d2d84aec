//! The network as the project's `Reconstructor`: stereo views in, the Gaussians the scene
//! needs out (those above the preset's opacity floor, at most its budget, the most opaque
//! kept), so the node and `eval` use the learned model exactly as they use the baseline.

use std::path::{Path, PathBuf};
use std::time::Instant;

use candle_core::{DType, Device, Tensor};
use candle_nn::VarBuilder;
use glam::{Quat, Vec3};
use renderer::{Camera, GaussianSet};

use super::config::weights_preset;
use super::depth_range::{rig_range, DepthRange};
use super::merge::merge_redundant;
use super::prune::prune_unseen;
use super::warm_start::{frozen, load_matching, WarmStart};
use super::{pair_fusion, Config, Prediction, StereoSplat};
use crate::ops::SplatTensors;
use crate::reconstruct::{ReconstructError, Reconstructor, StereoView};

/// The shipped weights of a preset, `stereosplat_<preset>.safetensors` (a `-plus` preset's
/// are its base preset's, see [`weights_preset`]), found as [`crate::assets`] says.
pub fn default_weights(preset: &str) -> PathBuf {
    crate::assets::weights_file(&format!(
        "stereosplat_{}.safetensors",
        weights_preset(preset)
    ))
}

/// Why weights could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// No file there (the preset has no shipped weights: train them with `stereosplat research
    /// train`).
    #[error("no weights at {0} (train them with `stereosplat research train`)")]
    Missing(PathBuf),
    /// The `device` setting names a device this build or machine does not have.
    #[error("device: {0}")]
    Device(#[source] candle_core::Error),
    /// The file is not safetensors or does not fit the preset's network.
    #[error("weights {path} do not fit the network: {source}")]
    Mismatch {
        /// The file.
        path: PathBuf,
        /// What candle said.
        source: candle_core::Error,
    },
}

/// The learned reconstructor.
pub struct LearnedReconstructor {
    net: StereoSplat,
    name: String,
    parameters: usize,
    last: Option<BranchReport>,
}

/// How the last reconstruction went, per branch (for `bench model` and logs).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct BranchReport {
    /// Milliseconds of the cost-volume branch (all pairs).
    pub cost_volume_ms: f64,
    /// Milliseconds of the volume branch (fusion, encoder, head); 0 when off.
    pub volume_ms: f64,
    /// Output Gaussians of the cost-volume branch (after pair fusion, floor and budget).
    pub cost_volume_gaussians: usize,
    /// Output Gaussians of the volume branch (after floor and budget).
    pub volume_gaussians: usize,
    /// The depth range the candidates spanned, when `auto_depth_range` chose one.
    pub depth_range: Option<DepthRange>,
    /// Milliseconds of the `auto_depth_range` fit (SGM on the first pair, whether or not
    /// the range was then used); 0 when off.
    pub range_fit_ms: f64,
}

impl LearnedReconstructor {
    /// The network of `cfg` with weights from `path` (safetensors, f32), on `cfg.device`.
    pub fn load(cfg: &Config, path: &Path) -> Result<Self, LoadError> {
        if !crate::assets::exists(path) {
            return Err(LoadError::Missing(path.to_path_buf()));
        }
        let device = cfg.device.open().map_err(LoadError::Device)?;
        let mismatch = |source| LoadError::Mismatch {
            path: path.to_path_buf(),
            source,
        };
        let tensors = crate::assets::load_tensors(path, &device).map_err(mismatch)?;
        let parameters = tensors.values().map(Tensor::elem_count).sum();
        let vb = VarBuilder::from_tensors(tensors, DType::F32, &device);
        let net = StereoSplat::new(vb, cfg).map_err(mismatch)?;
        Ok(Self::from_net(net, parameters))
    }

    /// The network of `cfg` with every weight `path` holds and fresh ones (candle's
    /// initialisers) for the rest: the shipped cost-volume weights under a network with the
    /// volume branch, before the branch is trained. The report names the fresh weights.
    pub fn warm_start(cfg: &Config, path: &Path) -> Result<(Self, WarmStart), LoadError> {
        if !crate::assets::exists(path) {
            return Err(LoadError::Missing(path.to_path_buf()));
        }
        let mismatch = |source| LoadError::Mismatch {
            path: path.to_path_buf(),
            source,
        };
        // The variables live on the device; `load_matching` moves the file's tensors there.
        let device = cfg.device.open().map_err(LoadError::Device)?;
        let varmap = candle_nn::VarMap::new();
        StereoSplat::new(VarBuilder::from_varmap(&varmap, DType::F32, &device), cfg)
            .map_err(mismatch)?;
        let report = load_matching(&varmap, path).map_err(mismatch)?;
        let tensors = frozen(&varmap).map_err(mismatch)?;
        let parameters = tensors.values().map(Tensor::elem_count).sum();
        let vb = VarBuilder::from_tensors(tensors, DType::F32, &device);
        let net = StereoSplat::new(vb, cfg).map_err(mismatch)?;
        Ok((Self::from_net(net, parameters), report))
    }

    /// The network of `cfg` with random weights (candle's initialisers): for timing presets
    /// that have no trained weights, and for tests of shapes and numerical stability.
    pub fn untrained(cfg: &Config) -> candle_core::Result<Self> {
        let varmap = candle_nn::VarMap::new();
        let vb = VarBuilder::from_varmap(&varmap, DType::F32, &cfg.device.open()?);
        let net = StereoSplat::new(vb, cfg)?;
        let parameters = varmap.all_vars().iter().map(|v| v.elem_count()).sum();
        Ok(Self::from_net(net, parameters))
    }

    /// Wraps a network with `parameters` weights in all.
    pub fn from_net(net: StereoSplat, parameters: usize) -> Self {
        let name = format!("stereosplat-{}", net.config().name);
        Self {
            net,
            name,
            parameters,
            last: None,
        }
    }

    /// Per-branch time and Gaussians of the last reconstruction.
    pub fn last_report(&self) -> Option<BranchReport> {
        self.last
    }

    /// Number of weights.
    pub fn parameters(&self) -> usize {
        self.parameters
    }

    /// The network.
    pub fn net(&self) -> &StereoSplat {
        &self.net
    }

    /// The device the network's weights live on (its inputs go there too).
    pub fn device(&self) -> Device {
        self.net.device()
    }
}

/// The views' images as one `(2K, 3, H, W)` tensor in `[0, 1]` (left, right, left, ...) and
/// their cameras. Errors if images differ in size or from their cameras' resolution.
pub fn images_and_cameras(
    views: &[StereoView<'_>],
    device: &Device,
) -> Result<(Tensor, Vec<Camera>), ReconstructError> {
    let first = views.first().ok_or(ReconstructError::NoViews)?;
    let (w, h) = (first.left.width, first.left.height);
    let mut data = Vec::with_capacity(views.len() * 6 * (w * h) as usize);
    let mut cameras = Vec::with_capacity(2 * views.len());
    for view in views {
        for (image, camera) in [
            (view.left, view.left_camera),
            (view.right, view.right_camera),
        ] {
            let k = camera.intrinsics;
            if (image.width, image.height) != (w, h) || (k.width, k.height) != (w, h) {
                return Err(ReconstructError::InvalidInput(format!(
                    "image {}x{} with camera {}x{}, expected {w}x{h}",
                    image.width, image.height, k.width, k.height
                )));
            }
            // Non-finite pixels would poison every feature: they become black.
            data.extend(
                image
                    .data
                    .iter()
                    .map(|v| if v.is_finite() { *v } else { 0.0 }),
            );
            cameras.push(camera);
        }
    }
    let backend = |e: candle_core::Error| ReconstructError::Backend(e.to_string());
    let images = Tensor::from_vec(data, (cameras.len(), h as usize, w as usize, 3), device)
        .and_then(|t| t.permute((0, 3, 1, 2))?.contiguous())
        .map_err(backend)?;
    Ok((images, cameras))
}

impl Reconstructor for LearnedReconstructor {
    fn name(&self) -> &str {
        &self.name
    }

    fn reconstruct(&mut self, views: &[StereoView<'_>]) -> Result<GaussianSet, ReconstructError> {
        let (images, cameras) = images_and_cameras(views, &self.device())?;
        Ok(self.reconstruct_tensors(&images, &cameras)?.set)
    }

    fn last_depth_range(&self) -> Option<(f32, f32)> {
        let range = self.last?.depth_range?;
        Some((range.near, range.far))
    }
}

/// A bin map with the cost-volume prediction it came from (what the progressive pass joins
/// its pseudo pairs to).
pub struct Reconstruction {
    /// The bin map, as [`Reconstructor::reconstruct`] returns it.
    pub set: GaussianSet,
    /// The cost-volume branch's prediction of the input views (no volume output).
    pub cost_volume: Prediction,
}

impl LearnedReconstructor {
    /// [`Reconstructor::reconstruct`] of `images` `(2K, 3, H, W)` in `[0, 1]` seen by
    /// `cameras` (see [`images_and_cameras`]), keeping the cost-volume prediction. With
    /// `auto_depth_range`, over the depth range the first pair shows.
    pub fn reconstruct_tensors(
        &mut self,
        images: &Tensor,
        cameras: &[Camera],
    ) -> Result<Reconstruction, ReconstructError> {
        let start = Instant::now();
        // The rig's range once; the network is only copied when a range or fit changes it.
        let rig = rig_range(cameras, self.net.config());
        let rigged = rig.map(|r| self.net.with_depth_range(r));
        let fitted = rigged
            .as_ref()
            .unwrap_or(&self.net)
            .fitted_to_scene(images, cameras);
        let range_fit_ms = match self.net.config().fits_scene() {
            true => start.elapsed().as_secs_f64() * 1e3,
            false => 0.0,
        };
        let (net, range) = match fitted {
            Some((fitted, range)) => (Some(fitted), range.or(rig)),
            None => (rigged, rig),
        };
        let out = match net {
            Some(net) => {
                let preset = std::mem::replace(&mut self.net, net);
                let out = self.reconstruct_over_preset_range(images, cameras);
                self.net = preset;
                out
            }
            None => self.reconstruct_over_preset_range(images, cameras),
        };
        if let Some(last) = &mut self.last {
            last.depth_range = range;
            last.range_fit_ms = range_fit_ms;
        }
        out
    }

    /// [`LearnedReconstructor::reconstruct_tensors`] with the network's own depth range.
    fn reconstruct_over_preset_range(
        &mut self,
        images: &Tensor,
        cameras: &[Camera],
    ) -> Result<Reconstruction, ReconstructError> {
        let backend = |e: candle_core::Error| ReconstructError::Backend(e.to_string());
        let cfg = self.net.config().clone();
        let start = Instant::now();
        let cost_volume = self
            .cost_volume_prediction(images, cameras)
            .map_err(backend)?;
        let cost_volume_ms = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        let prediction = self
            .net
            .with_volume(cost_volume.clone(), cameras)
            .map_err(backend)?;
        let volume_ms = start.elapsed().as_secs_f64() * 1e3;
        let counts = prediction.counts();
        // Pair fusion judges the cost-volume Gaussians against the views' depth; the volume
        // branch's Gaussians (after them in the output) are judged against every input view
        // when `volume_fusion_margin` is set, and all pass otherwise.
        let cost_volume_flags = match prediction.cost_volume_output {
            true => pair_fusion_flags(&prediction, cameras, &cfg, cfg.pair_fusion_margin)
                .map_err(backend)?,
            false => None,
        };
        let volume_flags = match (cfg.volume_fusion_margin, &prediction.volume) {
            (Some(margin), Some(volume)) => {
                // The volume's job is what the views did not see (`pair_fusion::unexplained`).
                let means = &volume.splats.means;
                let rule = pair_fusion::unexplained;
                Some(judged(&prediction, means, cameras, &cfg, margin, rule).map_err(backend)?)
            }
            _ => None,
        };
        let surviving = match (cost_volume_flags, volume_flags) {
            (None, None) => None,
            (cv, vol) => Some(
                [
                    cv.unwrap_or_else(|| vec![true; counts.cost_volume]),
                    vol.unwrap_or_else(|| vec![true; counts.volume]),
                ]
                .concat(),
            ),
        };
        let (set, kept) = to_set_counted(
            &prediction.output().map_err(backend)?,
            surviving.as_deref(),
            cfg.opacity_floor,
            cfg.max_gaussians,
            counts.cost_volume,
        )
        .map_err(backend)?;
        self.last = Some(BranchReport {
            cost_volume_ms,
            volume_ms: if prediction.volume.is_some() {
                volume_ms
            } else {
                0.0
            },
            cost_volume_gaussians: kept[0],
            volume_gaussians: kept[1],
            depth_range: None,
            range_fit_ms: 0.0,
        });
        let set = match (cfg.merge_tolerance, cameras.first()) {
            (Some(tolerance), Some(reference)) => {
                merge_redundant(&set, reference, cfg.gaussian_stride, tolerance)
            }
            _ => set,
        };
        let set = match cfg.min_view_weight {
            Some(min_weight) => prune_unseen(&set, cameras, min_weight),
            None => set,
        };
        Ok(Reconstruction { set, cost_volume })
    }

    /// The cost-volume branch's prediction of the views: all together when the preset's
    /// `joint_pairs` says so (or there is one pair), else pair by pair.
    pub fn cost_volume_prediction(
        &self,
        images: &Tensor,
        cameras: &[Camera],
    ) -> candle_core::Result<Prediction> {
        match self.net.config().joint_pairs || cameras.len() <= 2 {
            true => self.net.cost_volume(images, cameras),
            false => self.pair_by_pair(images, cameras),
        }
    }

    /// Each pair (views `2k`, `2k + 1`) through the cost-volume branch alone, the predictions
    /// joined in view order: the first pair's Gaussians are exactly what it gives alone. SGM's
    /// hints (`sgm_guidance`) were matched on the first pair and guide it only. (The volume
    /// branch then sees all views at once: it reasons in the bin frame.)
    fn pair_by_pair(&self, images: &Tensor, cameras: &[Camera]) -> candle_core::Result<Prediction> {
        let unguided = self.net.without_hints();
        let parts = (0..cameras.len() / 2)
            .map(|k| {
                let net = if k == 0 { &self.net } else { &unguided };
                net.cost_volume(&images.narrow(0, 2 * k, 2)?, &cameras[2 * k..2 * k + 2])
            })
            .collect::<candle_core::Result<Vec<_>>>()?;
        Prediction::cat(&parts)
    }
}

/// Which of the cost-volume Gaussians of `prediction` (of `cameras`' views, pair after pair)
/// survive the fusion of pairs (`pair_fusion`) with `margin` (the preset's
/// `pair_fusion_margin` for real pairs): `None` with one pair or no margin (all survive).
pub fn pair_fusion_flags(
    prediction: &Prediction,
    cameras: &[Camera],
    cfg: &Config,
    margin: Option<f32>,
) -> candle_core::Result<Option<Vec<bool>>> {
    match margin {
        Some(margin) if cameras.len() > 2 => {
            let means = &prediction.splats.means;
            judged(
                prediction,
                means,
                cameras,
                cfg,
                margin,
                pair_fusion::surviving,
            )
            .map(Some)
        }
        _ => Ok(None),
    }
}

/// A `pair_fusion` rule applied to the centres `means` `(G, 3)` against the depth the
/// prediction estimated for its views.
fn judged(
    prediction: &Prediction,
    means: &Tensor,
    cameras: &[Camera],
    cfg: &Config,
    margin: f32,
    rule: pair_fusion::Rule,
) -> candle_core::Result<Vec<bool>> {
    let (_, _, hg, wg) = prediction.depth.dims4()?;
    let values = |t: &Tensor| t.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>();
    Ok(rule(
        &values(means)?,
        &values(&prediction.depth)?,
        cameras,
        (hg, wg),
        cfg.gaussian_stride,
        margin,
    ))
}

/// The Gaussians whose opacity reaches `floor`, the `budget` most opaque if more, as a set;
/// only those marked in `surviving` (one flag per Gaussian) when given. Non-finite Gaussians
/// are dropped.
pub fn to_set(
    splats: &SplatTensors,
    surviving: Option<&[bool]>,
    floor: f32,
    budget: usize,
) -> candle_core::Result<GaussianSet> {
    Ok(to_set_counted(splats, surviving, floor, budget, 0)?.0)
}

/// [`to_set`], also counting the kept rows before `boundary` and from it (the cost-volume
/// and the volume branch's share of the output when the first `boundary` rows are the
/// cost-volume branch's).
pub fn to_set_counted(
    splats: &SplatTensors,
    surviving: Option<&[bool]>,
    floor: f32,
    budget: usize,
    boundary: usize,
) -> candle_core::Result<(GaussianSet, [usize; 2])> {
    let rows = |t: &Tensor| t.to_dtype(DType::F32)?.flatten_all()?.to_vec1::<f32>();
    let (means, scales, rots) = (
        rows(&splats.means)?,
        rows(&splats.log_scales)?,
        rows(&splats.rotations)?,
    );
    let (logits, colors, conf) = (
        rows(&splats.opacity_logits)?,
        rows(&splats.colors)?,
        rows(&splats.confidences)?,
    );
    if surviving.is_some_and(|s| s.len() != logits.len()) {
        candle_core::bail!(
            "{} Gaussians but a different number of fusion flags",
            logits.len()
        );
    }
    let opacity = |i: usize| 1.0 / (1.0 + (-logits[i]).exp());
    let finite = |i: usize| {
        means[3 * i..3 * i + 3]
            .iter()
            .chain(&scales[3 * i..3 * i + 3])
            .chain(&rots[4 * i..4 * i + 4])
            .chain(&colors[3 * i..3 * i + 3])
            .chain([&logits[i], &conf[i]])
            .all(|v| v.is_finite())
    };
    let mut keep: Vec<usize> = (0..logits.len())
        .filter(|&i| surviving.is_none_or(|s| s[i]) && opacity(i) >= floor && finite(i))
        .collect();
    if keep.len() > budget {
        keep.sort_by(|&a, &b| opacity(b).total_cmp(&opacity(a)).then(a.cmp(&b)));
        keep.truncate(budget);
        keep.sort_unstable();
    }
    let before = keep.partition_point(|&i| i < boundary);
    let counted = [before, keep.len() - before];
    let mut set = GaussianSet::with_capacity(keep.len());
    let v3 = |v: &[f32], i: usize| Vec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    for i in keep {
        let q = Quat::from_xyzw(
            rots[4 * i + 1],
            rots[4 * i + 2],
            rots[4 * i + 3],
            rots[4 * i],
        );
        let q = if q.length_squared() > 1e-12 {
            q.normalize()
        } else {
            Quat::IDENTITY
        };
        set.means.push(v3(&means, i));
        set.log_scales.push(v3(&scales, i));
        set.rotations.push(q);
        set.opacities.push(opacity(i));
        set.colors.push(v3(&colors, i).clamp(Vec3::ZERO, Vec3::ONE));
        set.confidences.push(conf[i]);
    }
    Ok((set, counted))
}
