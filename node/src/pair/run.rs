//! One pair through any reconstructor. The images are area-averaged down to the working size
//! (the node's own rule, [`InputLimits::working_size`], with a pixel budget), the pair is
//! checked for rectification there, the reconstructor runs on it with the intrinsics scaled
//! to match, and its Gaussians are rendered from the left camera at the input size: the
//! depth (and colour) of every method comes from the same rendering of its Gaussians, so
//! methods are compared on what they reconstruct, not on how they store it.
//!
//! The reconstruction goes through the node's per-bin self-check ([`SelfCheck`]): a map that
//! fails it is, by [`PairOptions::on_check_fail`], replaced by SGM's (the default), dimmed,
//! or kept and flagged in the summary, exactly as the node treats a bin.
//!
//! A pixel has depth where the rendered opacity reaches [`PairOptions::min_alpha`]: below it
//! no surface covers the pixel and the alpha-normalised depth of a faint fringe would be a
//! guess. Which depth the pixel gets is [`DepthRule`].

use std::time::Instant;

use glam::{Quat, Vec3};
use model::frame::{DepthMap, RgbImage};
use model::kitti360::resample::resample_area;
use model::reconstruct::{ReconstructError, Reconstructor, StereoView};
use renderer::{cpu, Camera, GaussianSet, RenderOutput, RenderSettings};

use super::images::same_size;
use super::rectified::{vertical_disparity, VerticalDisparity};
use super::{Calibration, PairError};
use crate::pipeline::self_check::{CheckOutcome, OnCheckFail, SelfCheck};
use crate::service::InputLimits;

/// The working pixel budget by default: a third of a KITTI-360 frame's 1408 x 376 (the
/// node's own budget). Measured on Aloe (1282x1110, docs/real-pairs.md, "One pair"): SGM's
/// bad-3 is 18.4% at 100k px, 17.0% here, 36.5% at the node's 529k px and 56.0% at full size,
/// where both methods' 200,000-Gaussian budget leaves a third of the pixels uncovered; the
/// `tiny` network takes 0.7, 1.5, 4.5 and 13.4 s on 2 CPU cores at those sizes.
pub const DEFAULT_WORKING_PIXELS: u64 = 1408 * 376 / 3;

/// Which depth of the rendering a pixel with depth gets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DepthRule {
    /// The surface depth (`RenderOutput::surface_depth`): the depth of the Gaussian whose
    /// blend takes the opacity to [`PairOptions::surface_opacity`] (else to one half; the
    /// expected depth where the opacity stays under one half). One surface's depth, where
    /// the expected depth at an edge blends the nearer and the farther surface into a depth
    /// on neither.
    #[default]
    Surface,
    /// The alpha-normalised expected depth everywhere.
    Expected,
}

impl DepthRule {
    /// The rule's name, as `reconstruct --depth` spells it.
    pub fn name(self) -> &'static str {
        match self {
            DepthRule::Surface => "surface",
            DepthRule::Expected => "expected",
        }
    }
}

/// The opacity at which [`DepthRule::Surface`] takes a pixel's depth by default: chosen on
/// the generated validation drives' input view among 0.5 (the median), 0.7, 0.85, 0.95,
/// 0.98 and 0.995, by the mean bad-3 of SGM, `tiny` and `tiny-3d` over desks, rooms and
/// streets (`results/input_view/`).
pub const SURFACE_OPACITY: f32 = 0.95;

/// Settings of [`reconstruct_pair`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairOptions {
    /// Most pixels the reconstructor is given; larger pairs are scaled down, aspect kept.
    pub working_pixels: u64,
    /// Largest median |vertical disparity| (input pixels) a pair may show.
    pub max_vertical_px: f32,
    /// Rendered opacity from which a pixel has depth.
    pub min_alpha: f32,
    /// Which depth of the rendering such a pixel gets.
    pub depth_rule: DepthRule,
    /// With [`DepthRule::Surface`]: the opacity at which the depth is taken.
    pub surface_opacity: f32,
    /// What to do when the reconstruction fails the self-check (`model::consistency`), as
    /// the node does per bin: by default SGM's reconstruction replaces it.
    pub on_check_fail: OnCheckFail,
}

impl Default for PairOptions {
    fn default() -> Self {
        Self {
            working_pixels: DEFAULT_WORKING_PIXELS,
            max_vertical_px: 2.0,
            min_alpha: 0.5,
            depth_rule: DepthRule::default(),
            surface_opacity: SURFACE_OPACITY,
            on_check_fail: OnCheckFail::default(),
        }
    }
}

/// What [`reconstruct_pair`] made.
pub struct PairReconstruction {
    /// The Gaussians, in the left camera's frame (OpenCV axes, metres).
    pub gaussians: GaussianSet,
    /// The size the reconstructor worked at.
    pub working: (u32, u32),
    /// The rectification check, in working pixels.
    pub vertical: VerticalDisparity,
    /// The same in input pixels.
    pub vertical_input_px: Option<f32>,
    /// The Gaussians rendered from the left camera at the input size; its depth is the
    /// pair's depth ([`PairOptions::depth_rule`]), zero where the pixel has no depth.
    pub render: RenderOutput,
    /// Left-camera z-depth at the input size, metres; 0 where there is none.
    pub depth: DepthMap,
    /// Which rendered depth `depth` holds ...
    pub depth_rule: DepthRule,
    /// ... and with [`DepthRule::Surface`], at which opacity.
    pub surface_opacity: Option<f32>,
    /// Seconds the reconstructor took (with the self-check and any SGM fallback).
    pub reconstruct_s: f64,
    /// The self-check of the reconstruction and what came of it.
    pub check: CheckOutcome,
    /// The depth range (near, far, metres) the learned model fitted to the pair
    /// (`auto_depth_range`); `None` when it used its preset's.
    pub depth_range_m: Option<(f32, f32)>,
}

/// The left and right cameras of a rectified rig with intrinsics `k`.
pub fn rig_cameras(k: renderer::Intrinsics, baseline: f64) -> (Camera, Camera) {
    (
        Camera::identity(k),
        Camera::from_camera_to_world(k, Quat::IDENTITY, Vec3::X * baseline as f32),
    )
}

/// Reconstructs the pair and renders it back (see the module documentation).
pub fn reconstruct_pair(
    left: &RgbImage,
    right: &RgbImage,
    calib: &Calibration,
    reconstructor: &mut dyn Reconstructor,
    options: &PairOptions,
) -> Result<PairReconstruction, PairError> {
    let size = (left.width, left.height);
    same_size("left and right images", size, (right.width, right.height))?;
    same_size(
        "calibration and images",
        (calib.intrinsics.width, calib.intrinsics.height),
        size,
    )?;
    let limits = InputLimits {
        max_working_width: u32::MAX,
        max_working_pixels: options.working_pixels.max(1),
        ..InputLimits::default()
    };
    let working = limits.working_size(size.0, size.1);
    let (wl, wr) = (
        resample_area(left, working.0, working.1),
        resample_area(right, working.0, working.1),
    );
    let vertical = vertical_disparity(&wl, &wr);
    let to_input = size.1 as f32 / working.1 as f32;
    let vertical_input_px = vertical.median_px.map(|v| v * to_input);
    if let Some(median_px) = vertical_input_px.filter(|v| *v > options.max_vertical_px) {
        return Err(PairError::NotRectified {
            median_px,
            patches: vertical.patches,
            limit_px: options.max_vertical_px,
        });
    }
    let k_working = match working == size {
        true => calib.intrinsics,
        false => calib.intrinsics.scaled(working.0, working.1),
    };
    let (left_camera, right_camera) = rig_cameras(k_working, calib.baseline);
    let started = Instant::now();
    let stereo = StereoView {
        left: &wl,
        right: &wr,
        left_camera,
        right_camera,
    };
    let gaussians = reconstructor
        .reconstruct(&[stereo])
        .map_err(PairError::Reconstruct)?;
    let depth_range_m = reconstructor.last_depth_range();
    let (gaussians, check) =
        SelfCheck::new(options.on_check_fail).apply(reconstructor.name(), &stereo, gaussians);
    let gaussians = gaussians.map_err(|e| PairError::Reconstruct(ReconstructError::Backend(e)))?;
    let reconstruct_s = started.elapsed().as_secs_f64();
    let view = gaussians
        .view()
        .map_err(|e| PairError::Gaussians(e.to_string()))?;
    let camera = Camera::identity(calib.intrinsics);
    let settings = RenderSettings {
        surface_opacity: options.surface_opacity,
        ..RenderSettings::default()
    };
    let mut render = cpu::render(&view, &camera.params::<f32>(), &settings).output;
    let mut depth = DepthMap::empty(size.0, size.1);
    let surface = options.depth_rule == DepthRule::Surface;
    for (i, out) in depth.data.iter_mut().enumerate() {
        let d = match surface && render.surface_depth[i] > 0.0 {
            true => render.surface_depth[i],
            false => render.depth[i],
        };
        render.depth[i] = match render.alpha[i] >= options.min_alpha && d.is_finite() && d > 0.0 {
            true => d,
            false => 0.0,
        };
        *out = render.depth[i];
    }
    Ok(PairReconstruction {
        gaussians,
        working,
        vertical,
        vertical_input_px,
        render,
        depth,
        depth_rule: options.depth_rule,
        surface_opacity: surface.then_some(options.surface_opacity),
        reconstruct_s,
        check,
        depth_range_m,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use renderer::{Gaussian, Intrinsics};

    /// A test double for a method: always the same two layers on the optical axis, a nearer
    /// one at 1 m that takes the opacity to 0.8 over a farther one at 5 m, so the
    /// depth rule alone decides the pair's depth (a network or SGM would make the same
    /// point less plainly).
    struct TwoLayers;

    impl Reconstructor for TwoLayers {
        fn name(&self) -> &str {
            "two-layers"
        }

        fn reconstruct(&mut self, _: &[StereoView<'_>]) -> Result<GaussianSet, ReconstructError> {
            let mut set = GaussianSet::default();
            for z in [1.0f32, 5.0] {
                set.push(Gaussian {
                    mean: Vec3::new(0.0, 0.0, z),
                    log_scale: Vec3::splat((10.0 * z).ln()),
                    rotation: Quat::IDENTITY,
                    opacity: 0.8,
                    color: Vec3::splat(0.5),
                    confidence: 1.0,
                });
            }
            Ok(set)
        }
    }

    fn depth_at_centre(rule: DepthRule, surface_opacity: f32) -> f32 {
        let (w, h) = (64, 48);
        let image = RgbImage::new(w, h);
        let calib = Calibration {
            intrinsics: Intrinsics::from_hfov(w, h, 60.0),
            baseline: 0.1,
        };
        let options = PairOptions {
            on_check_fail: OnCheckFail::Flag,
            depth_rule: rule,
            surface_opacity,
            ..PairOptions::default()
        };
        let pair = reconstruct_pair(&image, &image, &calib, &mut TwoLayers, &options).unwrap();
        let centre = (h / 2 * w + w / 2) as usize;
        assert_eq!(pair.render.depth[centre], pair.depth.data[centre]);
        pair.depth.data[centre]
    }

    #[test]
    fn the_surface_rule_gives_one_surface_and_the_expected_rule_a_blend() {
        assert!((depth_at_centre(DepthRule::Surface, 0.5) - 1.0).abs() < 1e-5);
        // The opacity reaches 0.95 only on the farther layer.
        assert!((depth_at_centre(DepthRule::Surface, 0.95) - 5.0).abs() < 1e-5);
        // (0.8 * 1 + 0.16 * 5) / 0.96 m, on neither surface.
        assert!((depth_at_centre(DepthRule::Expected, 0.95) - 1.667).abs() < 0.01);
    }
}
