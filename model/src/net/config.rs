//! The one preset struct: every setting of the network that trades speed for accuracy, with
//! named presets (`tiny`, `small`, `paper`) that every command selects by name.

use serde::{Deserialize, Serialize};

use super::volume::VolumeConfig;
use crate::compute::ComputeDevice;

/// The metric limits a rig-derived candidate range is kept within (metres): a safety clamp
/// for absurd rigs (a 1 mm or 2 m baseline), not a setting of the scene.
pub const RIG_DEPTH_LIMITS: (f32, f32) = (0.01, 10_000.0);

/// Sizes and ranges of the StereoSplat cost-volume network.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Config {
    /// The preset's name (`tiny`, `small`, `paper`), recorded in weight files and reports.
    pub name: String,
    /// Channels of the shared image backbone at 1/4 resolution.
    pub backbone_channels: usize,
    /// Residual blocks of the backbone at 1/4 resolution.
    pub backbone_blocks: usize,
    /// Channels of the monocular geometry encoder (the role of Depth-Anything-V2 features).
    pub mono_channels: usize,
    /// Residual blocks of the geometry encoder at 1/8 resolution.
    pub mono_blocks: usize,
    /// Multi-view transformer layers (each: windowed self-attention, cross-attention to the
    /// other views in the same window, MLP).
    pub transformer_layers: usize,
    /// Attention heads.
    pub heads: usize,
    /// Attention window (rows, columns) at 1/4 resolution.
    pub window: (usize, usize),
    /// Channels the per-view features are projected to before correlation.
    pub cost_channels: usize,
    /// Depth candidates of the plane sweep (the paper's disparity candidates).
    pub candidates: usize,
    /// Nearest depth candidate, metres.
    pub near: f32,
    /// Farthest depth candidate, metres (sky lands here).
    pub far: f32,
    /// Candidates from the rig instead of fixed metres: the nearest candidate is the depth
    /// whose disparity is this fraction of the image width (`fx * baseline / (fraction *
    /// width)`, the same for any image size of one lens), the farthest `far / near` times
    /// deeper, so the network's normalised inverse depth is normalised disparity and a
    /// desk seen by a 5 cm rig and a street seen by a 60 cm rig fill the same candidates.
    /// The range is kept within [`RIG_DEPTH_LIMITS`] metres. `None`: `near..far` in metres.
    #[serde(default)]
    pub rig_disparity_fraction: Option<f32>,
    /// How many nearest views (by camera translation) each reference view matches against.
    pub match_views: usize,
    /// With several input pairs, whether the network sees them together (views attend to and
    /// match views of other pairs, the paper's joint input) or each pair alone, as in
    /// single-pair training, before the pairs are fused. Inference only: training always
    /// feeds its sampled pairs together.
    #[serde(default)]
    pub joint_pairs: bool,
    /// With several input pairs, drop a later pair's Gaussians that an earlier view already
    /// explains: inside its image and less than this fraction behind its estimated surface
    /// (see `pair_fusion`; 1.0: kept only beyond twice the surface's depth). `None` keeps
    /// every pair's Gaussians. Inference only: training renders every Gaussian.
    #[serde(default)]
    pub pair_fusion_margin: Option<f32>,
    /// Channels of the U-Net depth head.
    pub unet_channels: usize,
    /// Bound on the U-Net's own depth logits (`b tanh(x / b)`), so that the correlation
    /// term, not a monocular guess, decides where matching is clear. `None`: unbounded;
    /// weights trained so let the U-Net's logits span about 500 across the candidates
    /// against the correlation's 6, and ignored the cost volume (`results/stereosplat_tiny/`).
    #[serde(default)]
    pub depth_logit_bound: Option<f32>,
    /// Add the soft census correlation of the grey images (`census_volume`) to the
    /// depth head's matching term at a learned weight from zero: a cost that a camera's gain,
    /// offset and texture statistics cannot move, so matching that transfers from the
    /// generated streets to real photographs.
    #[serde(default)]
    pub census_matching: bool,
    /// Spend the depth candidates on the depths the pair shows: SGM on the first pair (at
    /// the network's input size) measures its disparities and the candidates span them (2nd
    /// to 98th percentile, a 25% margin, at least a factor 3) inside `near..far` or the
    /// rig's range ([`super::depth_range`]). Off: always that range. Training with it on
    /// spans each sample's own range the same way, so the
    /// network learns its candidates relative to it (weights trained without it read them as
    /// fixed depths, and the streets break under it). Pseudo pairs of the progressive pass
    /// keep `near..far`.
    #[serde(default)]
    pub auto_depth_range: bool,
    /// With `auto_depth_range`: fit only scenes whose fitted far end lies below this many
    /// metres, and keep `near..far` for deeper ones. Streets reach the sky and fit to 90 m
    /// and beyond, rooms to about 10 m, so a bound between them narrows the candidates for
    /// near scenes and leaves streets exactly as the weights learned them. `None`: fit every
    /// scene.
    #[serde(default)]
    pub auto_depth_range_max_far: Option<f32>,
    /// Guided stereo matching with SGM's own matches as hints ([`super::guidance`]): the
    /// depth head's logits gain a bump of this height about the candidate SGM matched, on
    /// the cells of the first pair where SGM matched consistently, on scenes whose fitted far
    /// end passes `auto_depth_range_max_far` (near scenes only: on the streets SGM is the
    /// weaker matcher, and its hints pull the network off). The same SGM run as
    /// `auto_depth_range`'s fit, run for this even when the range is not used. The bump's
    /// width is [`super::guidance::GUIDANCE_WIDTH`]. `None`: off. Training with it set adds
    /// each sample's hints, as inference does.
    #[serde(default)]
    pub sgm_guidance: Option<f32>,
    /// Channels of the Gaussian heads.
    pub head_channels: usize,
    /// With `sgm_guidance`'s hints present (near scenes): each Gaussian of the first pair
    /// whose pixels SGM matched consistently takes SGM's depth instead of the network's; the
    /// network's depth fills the rest and the network sets every Gaussian's colour, opacity,
    /// shape and offset. A hybrid (the network alone cannot place real foreground edges:
    /// it draws them over their background), inference only.
    #[serde(default)]
    pub sgm_snap: bool,
    /// With `sgm_guidance`'s hints present (near scenes): the pixels SGM left unmatched take
    /// the farther of the nearest matches on their row before the hints guide the network
    /// and the snap places Gaussians ([`super::hint_fill`]), so half-occlusions and weakly
    /// textured surfaces get the classical disparity around them, not the network's guess.
    /// The range fit reads SGM's own matches only.
    #[serde(default)]
    pub sgm_fill: bool,
    /// One Gaussian per `gaussian_stride` x `gaussian_stride` pixels of each view.
    pub gaussian_stride: usize,
    /// Gaussians below this opacity are not emitted.
    pub opacity_floor: f32,
    /// At most this many Gaussians per reconstruction (the most opaque are kept).
    pub max_gaussians: usize,
    /// Merge redundant Gaussians (2x2 blocks whose relative depth and colour agree within
    /// this tolerance, see `merge`) so flat regions take fewer; `None` keeps one per
    /// `gaussian_stride` pixels everywhere. Inference only.
    #[serde(default)]
    pub merge_tolerance: Option<f32>,
    /// Drop the Gaussians whose blend weight summed over the input views is below this many
    /// pixels (hidden behind nearer ones, outside every image, too faint; see `prune`);
    /// `None` keeps them. Inference only.
    #[serde(default)]
    pub min_view_weight: Option<f32>,
    /// Whether the cost-volume branch's Gaussians are part of the output (its features
    /// still guide the volume branch when it is off: the paper's Branch_3D row).
    #[serde(default = "yes")]
    pub cost_volume_branch: bool,
    /// Whether the 3D-volume (triplane) branch runs and adds its Gaussians.
    #[serde(default)]
    pub volume_branch: bool,
    /// Drop the volume branch's Gaussians that an input view already explains: inside its
    /// image and less than this fraction behind its estimated surface (`pair_fusion`), so
    /// the volume adds only what the views did not see; `None` keeps them all. Inference
    /// only: training renders every Gaussian.
    #[serde(default)]
    pub volume_fusion_margin: Option<f32>,
    /// With `volume_branch`: skip the branch on scenes SGM's fit finds nearer than
    /// `auto_depth_range_max_far` ([`super::StereoSplat::fitted_to_scene`]; the fit runs with
    /// `auto_depth_range` or `sgm_guidance`). Its grid is street-sized (`volume`'s extent),
    /// and on a room it draws Gaussians behind the surfaces (`results/tiny_3d/`).
    /// Inference only.
    #[serde(default)]
    pub volume_branch_far_only: bool,
    /// Sizes of the volume branch (`--set volume.top_k=2000` changes one).
    #[serde(default)]
    pub volume: VolumeConfig,
    /// Training only: draw the number and placement of input pairs at random (the paper's
    /// stochastic view subsampling); off, the input is the bin's first pair (what `train
    /// --no-subsample` also asks).
    #[serde(default = "yes")]
    pub view_subsampling: bool,
    /// Inference: StereoSplat+'s progressive pass (`model::progressive`): the bin map
    /// G_base from the real pairs, pseudo stereo pairs rendered from it at the poses ahead,
    /// enhanced, fed back as input pairs, and the Gaussians they add fused in by confidence.
    #[serde(default)]
    pub progressive: bool,
    /// With `progressive`: pass the pseudo views through the one-step enhancer
    /// (`model::enhance`); off re-injects the raw renders (the paper's ablation row).
    #[serde(default = "yes")]
    pub enhancer: bool,
    /// With `progressive` and `enhancer`: the enhancer's weights (`None`: the shipped
    /// `model/weights/enhancer_tiny.safetensors`).
    #[serde(default)]
    pub enhancer_weights: Option<std::path::PathBuf>,
    /// With `progressive`: run the pass on every n-th bin only (1: every bin), the others
    /// publish G_base; the node's per-bin choice when the whole pass cannot keep up with the
    /// drive (the worker queue's keep-newest policy and drop counters stay as they are).
    #[serde(default = "one")]
    pub progressive_every: usize,
    /// With `progressive`: one pseudo pair per entry, at these metres ahead of the last
    /// input camera along the trajectory when the bin's later poses are not known (the node
    /// opens a bin at its first frame); with them known (`eval`), at the bin's own later
    /// poses, evenly spaced and ending at the last (`[4, 8]`: centre and last).
    #[serde(default = "pseudo_poses")]
    pub pseudo_poses: Vec<f32>,
    /// With `progressive`: a pseudo pair's Gaussian is added only where no earlier view
    /// explains it (`pair_fusion`), here "more than this fraction behind that view's surface"
    /// (or outside it): the disoccluded space the pass exists to fill. 1 (the real pairs'
    /// own margin) adds about 3% to G_base and wins PSNR, LPIPS and unseen-region PSNR
    /// together; 0.1 adds about 30%, fills more of the unseen regions and gains more PSNR, but
    /// the extra layers blur (LPIPS worse): `bash scripts/eval_progressive.sh`,
    /// `results/progressive/`.
    #[serde(default = "pseudo_fusion_margin")]
    pub pseudo_fusion_margin: f32,
    /// With `progressive`: an added pseudo Gaussian's opacity is multiplied by its
    /// confidence to this power (1: opacity x confidence; 0: confidence ignored; 2: doubtful
    /// guesses fade faster).
    #[serde(default = "one_f32")]
    pub pseudo_confidence_power: f32,
    /// Training: probability that each sampled input pair after the first is replaced by a
    /// pseudo pair rendered from the current model (the paper's pseudo-view mixed training);
    /// 0 trains on true pairs only.
    #[serde(default)]
    pub pseudo_mix: f32,
    /// Where the network runs: `cpu` (default) or `cuda` / `cuda:N` (a build with the `cuda`
    /// feature; `crate::compute`). Not part of the network: weights load on either.
    #[serde(default)]
    pub device: ComputeDevice,
}

fn yes() -> bool {
    true
}

fn one() -> usize {
    1
}

fn one_f32() -> f32 {
    1.0
}

fn pseudo_fusion_margin() -> f32 {
    1.0
}

/// Pseudo pairs at the centre and the end of an 8 m bin (`BinConfig::default`).
fn pseudo_poses() -> Vec<f32> {
    vec![4.0, 8.0]
}

/// The preset names [`Config::preset`] knows.
pub const PRESETS: &[&str] = &["tiny", "small", "paper", "tiny-plus", "tiny-3d"];

/// The presets named `<base>-plus` are `<base>` with StereoSplat+'s progressive pass on: the
/// same network, so they load `<base>`'s weights. The preset whose weights `name` uses.
pub fn weights_preset(name: &str) -> &str {
    name.strip_suffix("-plus").unwrap_or(name)
}

/// A preset name [`Config::preset`] does not know.
#[derive(Debug, thiserror::Error)]
#[error("unknown preset `{0}` (known: {known})", known = PRESETS.join(", "))]
pub struct UnknownPreset(pub String);

/// A `KEY=VALUE` setting [`Config::with_settings`] cannot apply.
#[derive(Debug, thiserror::Error)]
pub enum SettingError {
    /// Not of the form `KEY=VALUE`.
    #[error("setting `{0}` is not KEY=VALUE")]
    Malformed(String),
    /// No field of the preset has this name.
    #[error("no preset setting `{0}`")]
    UnknownKey(String),
    /// The value does not fit the field (numbers, `true`/`false`, `null`, `[a, b]`).
    #[error("setting `{key}` cannot be `{value}`: {reason}")]
    Invalid {
        /// The field.
        key: String,
        /// The value as given.
        value: String,
        /// What the parser said.
        reason: String,
    },
}

/// `value` with fields changed by `KEY=VALUE` settings (values in JSON: `0.1`, `true`,
/// `null`, `[4, 16]`; anything else is a string; `a.b` names a nested field). Any settings
/// type that serialises to a JSON object takes them: the network's presets and the SGM
/// baseline's [`crate::baseline::SgmConfig`].
pub fn apply_settings<T, S>(value: T, settings: &[S]) -> Result<T, SettingError>
where
    T: Serialize + serde::de::DeserializeOwned,
    S: AsRef<str>,
{
    settings.iter().try_fold(value, |cfg, setting| {
        let setting = setting.as_ref();
        let (key, value) = setting
            .split_once('=')
            .ok_or_else(|| SettingError::Malformed(setting.to_string()))?;
        let (key, value) = (key.trim(), value.trim());
        let mut fields = match serde_json::to_value(&cfg) {
            Ok(map @ serde_json::Value::Object(_)) => map,
            _ => unreachable!("settings types serialise to JSON objects"),
        };
        let slot = key
            .split('.')
            .try_fold(&mut fields, |node, part| node.get_mut(part))
            .filter(|_| !key.is_empty())
            .ok_or_else(|| SettingError::UnknownKey(key.to_string()))?;
        *slot = serde_json::from_str(value)
            .unwrap_or_else(|_| serde_json::Value::String(value.to_string()));
        serde_json::from_value(fields).map_err(|e| SettingError::Invalid {
            key: key.to_string(),
            value: value.to_string(),
            reason: e.to_string(),
        })
    })
}

impl Config {
    /// This preset with fields changed by `KEY=VALUE` settings ([`apply_settings`]), so
    /// every speed and accuracy trade can be tried from the command line without a new
    /// preset.
    pub fn with_settings<S: AsRef<str>>(self, settings: &[S]) -> Result<Self, SettingError> {
        apply_settings(self, settings)
    }

    /// Real time on a 2-core CPU: small channels, 32 candidates, Gaussians at 1/2 resolution.
    /// The matching term adds the census correlation, which a real camera's gain and texture
    /// cannot move. The candidates follow the rig: the nearest at the depth whose disparity
    /// is 0.233181 of the width (KITTI-360's `fx * baseline / width` at 1 m, so on the rig
    /// the weights learned they are exactly its 1-100 m, and a desk seen by a 10 cm rig gets
    /// candidates at its own disparities). One SGM run on the first pair, at the network's
    /// input size, then serves four aids on scenes whose fitted far end lies under 50 m
    /// (rooms, desks): the candidates span the disparities SGM found, SGM's matches, with
    /// the unmatched pixels filled from their row's farther neighbouring match (`sgm_fill`),
    /// guide the depth head (`sgm_guidance` 10, width 2 candidates), and the first pair's
    /// Gaussians take that depth where it is consistent (`sgm_snap`); the network fills the
    /// rest and sets every Gaussian's appearance. Streets reach beyond 50 m and run
    /// exactly as the weights learned them. Each setting was kept, changed or removed on
    /// generated validation drives (`bash scripts/setting_choices.sh`,
    /// `results/setting_choices/`; real pairs are only reported, `results/real_pairs/`). The
    /// shipped weights learned the census on the generated transfer mix (plain streets,
    /// domain-randomised drives, near objects: `scripts/transfer_data.sh`), first without
    /// the near-scene aids (`scripts/train_tiny_census.sh`), then with the fitted range and
    /// SGM's hints on every sample (`scripts/train_tiny_guided.sh`;
    /// `results/stereosplat_tiny/`).
    pub fn tiny() -> Self {
        Self {
            name: "tiny".into(),
            backbone_channels: 32,
            backbone_blocks: 1,
            mono_channels: 16,
            mono_blocks: 1,
            transformer_layers: 1,
            heads: 2,
            window: (4, 16),
            cost_channels: 32,
            candidates: 32,
            near: 1.0,
            far: 100.0,
            // On validation desks AbsRel 2.23 with metres, 0.20 with these candidates;
            // rooms and streets unchanged (`results/setting_choices/`).
            rig_disparity_fraction: Some(0.233181),
            match_views: 2,
            joint_pairs: false,
            pair_fusion_margin: Some(1.0),
            unet_channels: 32,
            depth_logit_bound: Some(4.0),
            census_matching: true,
            auto_depth_range: true,
            auto_depth_range_max_far: Some(50.0),
            sgm_guidance: Some(10.0),
            head_channels: 24,
            sgm_snap: true,
            sgm_fill: true,
            gaussian_stride: 2,
            opacity_floor: 0.02,
            max_gaussians: 200_000,
            merge_tolerance: None,
            min_view_weight: None,
            cost_volume_branch: true,
            volume_branch: false,
            volume_fusion_margin: None,
            volume_branch_far_only: false,
            volume: VolumeConfig::tiny(),
            view_subsampling: true,
            progressive: false,
            progressive_every: 1,
            enhancer: true,
            enhancer_weights: None,
            pseudo_poses: pseudo_poses(),
            pseudo_fusion_margin: pseudo_fusion_margin(),
            pseudo_confidence_power: one_f32(),
            pseudo_mix: 0.0,
            device: ComputeDevice::Cpu,
        }
    }

    /// Twice the channels and candidates of `tiny`, two transformer layers. One residual block
    /// per encoder, as `tiny`: with two (no normalisation in the blocks) training stalled at
    /// LPIPS 0.68 where one block reaches 0.47 in the same 400 steps (`stereosplat research
    /// train --preset small --steps 400` on the plain street drives,
    /// `results/stereosplat_small/`). Without `tiny`'s census correlation and fitted range: no
    /// `small` weights were trained with them.
    pub fn small() -> Self {
        Self {
            name: "small".into(),
            backbone_channels: 64,
            backbone_blocks: 1,
            mono_channels: 32,
            mono_blocks: 1,
            transformer_layers: 2,
            heads: 4,
            window: (4, 16),
            cost_channels: 64,
            candidates: 64,
            unet_channels: 48,
            head_channels: 48,
            volume: VolumeConfig::small(),
            ..Self::tiny().without_tiny_extras()
        }
    }

    /// The paper's settings: 192 candidates, Gaussians at full resolution, six transformer
    /// layers (DepthSplat's), 128-channel features; without `tiny`'s census correlation and
    /// fitted range, as `small`.
    pub fn paper() -> Self {
        Self {
            name: "paper".into(),
            backbone_channels: 128,
            backbone_blocks: 3,
            mono_channels: 64,
            mono_blocks: 4,
            transformer_layers: 6,
            heads: 4,
            window: (8, 16),
            cost_channels: 128,
            candidates: 192,
            match_views: 2,
            unet_channels: 64,
            head_channels: 64,
            gaussian_stride: 1,
            max_gaussians: 2_000_000,
            volume: VolumeConfig::paper(),
            ..Self::tiny().without_tiny_extras()
        }
    }

    /// `tiny` with StereoSplat+'s progressive pass on, the enhancer included (the shipped
    /// `tiny` weights and `model/weights/enhancer_tiny.safetensors`), with one pseudo pair at
    /// the end of the bin: two pairs cost the 2-core CPU about 1 s per bin at 544x112, over
    /// the 0.8 s a bin lasts at 10 m/s, and one keeps most of the gain
    /// (`bash scripts/eval_progressive.sh`, `results/progressive/`).
    pub fn tiny_plus() -> Self {
        Self {
            name: "tiny-plus".into(),
            progressive: true,
            pseudo_poses: vec![8.0],
            ..Self::tiny()
        }
    }

    /// `tiny` with the 3D-volume branch beside the cost volume (the paper's CV + 3D row) and
    /// its own weights (`model/weights/stereosplat_tiny-3d.safetensors`, `bash
    /// scripts/reproduce_weights.sh tiny-3d`), for a mapping stack that wants the depth
    /// first. The volume's Gaussians that an input view already explains are dropped
    /// (`volume_fusion_margin` 0.5). Its weights start from `tiny` weights trained without
    /// the census correlation, so it runs without it. On near
    /// scenes it takes `tiny`'s aids that need no census (the candidates from the rig, the
    /// depth range fitted under 50 m, SGM's filled hints, `sgm_snap`) and leaves its street-sized
    /// volume branch out (`volume_branch_far_only`). Those settings
    /// (`SETTING_PRESET=tiny-3d bash scripts/setting_choices.sh`,
    /// `results/setting_choices/tiny-3d/`), the weights' blend of its two training phases
    /// (`results/tiny_3d/chain/choice/`) and the step of its last stage, on desks, rooms and
    /// streets at 544x112 (`results/tiny_3d/scales/`), were chosen on generated validation
    /// drives. Reported, never chosen on (`results/tiny_3d/`): on the held-out streets AbsRel
    /// 0.126 against `tiny`'s 0.137 at 22.88 against 22.81 dB, and 19.10 against 18.73 dB
    /// where the input pair saw nothing; on real pairs Aloe 13.4% bad-3 (SGM 17.0%),
    /// Motorcycle 10.0% (SGM 12.8%).
    pub fn tiny_3d() -> Self {
        Self {
            name: "tiny-3d".into(),
            volume_branch: true,
            volume_fusion_margin: Some(0.5),
            view_subsampling: false,
            auto_depth_range: true,
            auto_depth_range_max_far: Some(50.0),
            sgm_guidance: Some(10.0),
            sgm_snap: true,
            sgm_fill: true,
            volume_branch_far_only: true,
            rig_disparity_fraction: Self::tiny().rig_disparity_fraction,
            ..Self::tiny().without_tiny_extras()
        }
    }

    /// Whether the first pair is matched by SGM before the network runs: for the fitted
    /// depth range, SGM's hints, or both ([`super::StereoSplat::fitted_to_scene`]).
    pub fn fits_scene(&self) -> bool {
        self.auto_depth_range || self.sgm_guidance.is_some()
    }

    /// These settings without what only `tiny`'s own weights were trained with or measured
    /// with (the census correlation, the fitted depth range, SGM's hints, the rig-derived
    /// candidates), for the presets built on `tiny` that have other weights or none.
    fn without_tiny_extras(self) -> Self {
        Self {
            sgm_snap: false,
            sgm_fill: false,
            census_matching: false,
            auto_depth_range: false,
            auto_depth_range_max_far: None,
            sgm_guidance: None,
            rig_disparity_fraction: None,
            ..self
        }
    }

    /// The preset called `name`.
    pub fn preset(name: &str) -> Result<Self, UnknownPreset> {
        match name {
            "tiny" => Ok(Self::tiny()),
            "small" => Ok(Self::small()),
            "paper" => Ok(Self::paper()),
            "tiny-plus" => Ok(Self::tiny_plus()),
            "tiny-3d" => Ok(Self::tiny_3d()),
            other => Err(UnknownPreset(other.to_string())),
        }
    }

    /// Features of one view that enter the cost volume: geometry plus transformer output.
    pub fn view_channels(&self) -> usize {
        self.backbone_channels + self.mono_channels
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_named_preset_resolves_to_itself() {
        for name in PRESETS {
            assert_eq!(Config::preset(name).unwrap().name, *name);
        }
        assert!(Config::preset("huge").is_err());
        assert_eq!(Config::paper().candidates, 192);
    }

    #[test]
    fn settings_change_named_fields_and_reject_the_rest() {
        let cfg = Config::tiny()
            .with_settings(&[
                "candidates=48",
                "pair_fusion_margin = 0.25",
                "window=[2, 8]",
            ])
            .unwrap();
        assert_eq!(cfg.candidates, 48);
        assert_eq!(cfg.pair_fusion_margin, Some(0.25));
        assert_eq!(cfg.window, (2, 8));
        let cfg = cfg
            .with_settings(&[
                "volume_branch=true",
                "volume.top_k=100",
                "volume.cells=[8, 4, 8]",
            ])
            .unwrap();
        assert!(cfg.volume_branch && cfg.cost_volume_branch);
        assert_eq!((cfg.volume.top_k, cfg.volume.cells), (100, [8, 4, 8]));
        assert_eq!(
            cfg.with_settings(&["pair_fusion_margin=null"])
                .unwrap()
                .pair_fusion_margin,
            None
        );
        let err = |s: &str| Config::tiny().with_settings(&[s]).unwrap_err();
        assert!(matches!(err("candidates"), SettingError::Malformed(_)));
        assert!(matches!(err("colour=3"), SettingError::UnknownKey(k) if k == "colour"));
        assert!(matches!(err("volume.size=3"), SettingError::UnknownKey(_)));
        assert!(matches!(
            err("volume.cells=[1, 2]"),
            SettingError::Invalid { .. }
        ));
        assert!(
            matches!(err("candidates=many"), SettingError::Invalid { key, .. } if key == "candidates")
        );
        assert!(matches!(err("candidates=-3"), SettingError::Invalid { .. }));
    }
}
