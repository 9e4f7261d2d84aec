//! The files `stereosplat reconstruct` writes into its output folder:
//!
//! - `gaussians.ply`: the reconstruction, 3DGS PLY, in the left camera's frame;
//! - `depth.png`: left-camera z-depth, 16-bit grey in the KITTI depth convention (metres x
//!   256, rounded, 0 = no depth; depths beyond 255.99 m are written as 65535);
//! - `depth_color.png`: the same through the renderer's colour map (near bright, no depth
//!   black), for people;
//! - `render.png`: the Gaussians rendered from the left camera;
//! - `photometric_error.png` (and `disparity_error.png` with a ground truth): per-pixel error
//!   through the colour map (0 dark, the scale's top and above bright, unscored black);
//! - `photometric_error16.png`: the photometric error as 16-bit grey, 1 + error x 65534
//!   (0 = not scored), so methods can be compared on the pixels both score;
//! - `summary.json`: [`Summary`].

use std::path::Path;

use image::{ExtendedColorType, ImageFormat};
use model::frame::DepthMap;
use renderer::picture::{save_depth_png, save_rgb_png, viridis, DepthScale, PictureError};
use renderer::RenderOutput;
use serde::Serialize;

use super::photometric::Photometric;
use super::rectified::VerticalDisparity;
use super::truth::DisparityScores;
use super::{Calibration, PairError, PairReconstruction};
use crate::pipeline::self_check::{CheckAction, CheckOutcome};

/// Top of the photometric error map's scale (mean |difference| in [0, 1]).
pub const PHOTOMETRIC_SCALE: f32 = 0.25;
/// Top of the disparity error map's scale, pixels.
pub const DISPARITY_SCALE: f32 = 8.0;

/// What `summary.json` holds.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// The reconstructor's name.
    pub method: String,
    /// Input image size.
    pub input_size: (u32, u32),
    /// Size the reconstructor worked at.
    pub working_size: (u32, u32),
    /// Focal lengths, principal point (input pixels) and baseline (metres).
    pub fx: f32,
    /// See `fx`.
    pub fy: f32,
    /// See `fx`.
    pub cx: f32,
    /// See `fx`.
    pub cy: f32,
    /// See `fx`.
    pub baseline_m: f64,
    /// The rectification check (working pixels) ...
    pub vertical: VerticalDisparity,
    /// ... and its median in input pixels.
    pub vertical_input_px: Option<f32>,
    /// Gaussians in the PLY.
    pub gaussians: usize,
    /// Seconds the reconstructor took.
    pub reconstruct_s: f64,
    /// The depth range (near, far, metres) the learned model fitted to the pair with
    /// `auto_depth_range`; null when it used its preset's.
    pub depth_range_m: Option<[f32; 2]>,
    /// Which rendered depth the depth files hold (`surface` or `expected`, `--depth`) ...
    pub depth_rule: &'static str,
    /// ... and with `surface`, at which opacity (`--surface-opacity`).
    pub surface_opacity: Option<f32>,
    /// Percent of left pixels with depth.
    pub depth_density: f64,
    /// Depth percentiles 5, 50, 95 over pixels with depth, metres.
    pub depth_percentiles_m: Option<[f32; 3]>,
    /// Photometric consistency.
    pub photometric: Photometric,
    /// Scores against the ground truth, when one was given.
    pub truth: Option<DisparityScores>,
    /// The self-check and what came of it.
    pub check: CheckSummary,
}

/// The self-check of a pair's reconstruction, as `summary.json` holds it.
#[derive(Clone, Debug, Serialize)]
pub struct CheckSummary {
    /// `pass`, `fail` or `undetermined`: the verdict on the method's own reconstruction.
    pub verdict: &'static str,
    /// Fraction of sampled patches that correlate between left and right, in [0, 1].
    pub score: f32,
    /// Fraction of the textured cells sampled.
    pub coverage: f32,
    /// What was done: `none`, `flagged`, `lowered_opacity` or `sgm` (SGM's map written).
    pub action: &'static str,
    /// SGM's verdict and score when it replaced the method's map.
    pub fallback: Option<(&'static str, f32)>,
    /// Whether the map written failed its check.
    pub flagged: bool,
}

impl CheckSummary {
    /// The summary of a check's outcome.
    pub fn new(outcome: &CheckOutcome) -> Self {
        let primary = outcome.primary;
        Self {
            verdict: primary.map_or("not run", |r| r.verdict.name()),
            score: primary.map_or(0.0, |r| r.score),
            coverage: primary.map_or(0.0, |r| r.coverage),
            action: match outcome.action {
                CheckAction::None => "none",
                CheckAction::Flagged => "flagged",
                CheckAction::LoweredOpacity => "lowered_opacity",
                CheckAction::Sgm => "sgm",
            },
            fallback: outcome.fallback.map(|r| (r.verdict.name(), r.score)),
            flagged: outcome.flagged(),
        }
    }
}

impl Summary {
    /// The summary of a reconstruction and its scores.
    pub fn new(
        method: &str,
        calib: &Calibration,
        pair: &PairReconstruction,
        photometric: Photometric,
        truth: Option<DisparityScores>,
    ) -> Self {
        let k = calib.intrinsics;
        let mut valid: Vec<f32> = pair
            .depth
            .data
            .iter()
            .copied()
            .filter(|d| *d > 0.0)
            .collect();
        valid.sort_by(f32::total_cmp);
        let at = |p: f32| valid[((valid.len() - 1) as f32 * p).round() as usize];
        Self {
            method: method.to_string(),
            input_size: (k.width, k.height),
            working_size: pair.working,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            baseline_m: calib.baseline,
            vertical: pair.vertical,
            vertical_input_px: pair.vertical_input_px,
            gaussians: pair.gaussians.len(),
            reconstruct_s: pair.reconstruct_s,
            depth_range_m: pair.depth_range_m.map(|(near, far)| [near, far]),
            depth_rule: pair.depth_rule.name(),
            surface_opacity: pair.surface_opacity,
            depth_density: 100.0 * valid.len() as f64 / pair.depth.data.len().max(1) as f64,
            depth_percentiles_m: (!valid.is_empty()).then(|| [at(0.05), at(0.5), at(0.95)]),
            photometric,
            truth,
            check: CheckSummary::new(&pair.check),
        }
    }
}

/// Writes a buffer as a PNG.
fn save_png(
    path: &Path,
    buf: &[u8],
    size: (u32, u32),
    color: ExtendedColorType,
) -> Result<(), PairError> {
    image::save_buffer_with_format(path, buf, size.0, size.1, color, ImageFormat::Png)
        .map_err(|e| PairError::Picture(PictureError::Encode(e)))
}

/// `depth.png`: metres x 256 as 16-bit grey, 0 where there is no depth.
pub fn save_depth16(path: &Path, depth: &DepthMap) -> Result<(), PairError> {
    let bytes: Vec<u8> = depth
        .data
        .iter()
        .map(|&z| match z > 0.0 && z.is_finite() {
            true => (z as f64 * 256.0).round().clamp(1.0, 65535.0) as u16,
            false => 0,
        })
        .flat_map(u16::to_ne_bytes)
        .collect();
    let size = (depth.width, depth.height);
    save_png(path, &bytes, size, ExtendedColorType::L16)
}

/// An error map through the colour map: 0 dark, `top` and above bright, NaN black,
/// infinite (no prediction) mid grey.
pub fn save_error_map(
    path: &Path,
    errors: &[f32],
    size: (u32, u32),
    top: f32,
) -> Result<(), PairError> {
    let rgb: Vec<u8> = errors
        .iter()
        .flat_map(|&e| match e {
            e if e.is_nan() => [0; 3],
            e if e.is_infinite() => [128; 3],
            e => viridis(e / top),
        })
        .collect();
    save_png(path, &rgb, size, ExtendedColorType::Rgb8)
}

/// `photometric_error16.png` (see the module documentation).
pub fn save_error16(path: &Path, errors: &[f32], size: (u32, u32)) -> Result<(), PairError> {
    let bytes: Vec<u8> = errors
        .iter()
        .map(|&e| match e.is_finite() {
            true => 1 + (e.clamp(0.0, 1.0) * 65534.0).round() as u16,
            false => 0,
        })
        .flat_map(u16::to_ne_bytes)
        .collect();
    save_png(path, &bytes, size, ExtendedColorType::L16)
}

/// Writes the reconstruction's files and the summary into `dir` (created).
pub fn write_all(
    dir: &Path,
    pair: &PairReconstruction,
    summary: &Summary,
    truth_errors: Option<(&[f32], (u32, u32))>,
) -> Result<(), PairError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| PairError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    renderer::ply::save_ply(&pair.gaussians, dir.join("gaussians.ply")).map_err(PairError::Ply)?;
    save_depth16(&dir.join("depth.png"), &pair.depth)?;
    let render: &RenderOutput = &pair.render;
    save_depth_png(render, dir.join("depth_color.png"), DepthScale::Auto)
        .map_err(PairError::Picture)?;
    save_rgb_png(render, dir.join("render.png")).map_err(PairError::Picture)?;
    let size = (render.width, render.height);
    let errors = &summary.photometric.errors;
    save_error_map(
        &dir.join("photometric_error.png"),
        errors,
        size,
        PHOTOMETRIC_SCALE,
    )?;
    save_error16(&dir.join("photometric_error16.png"), errors, size)?;
    if let Some((errors, size)) = truth_errors {
        save_error_map(
            &dir.join("disparity_error.png"),
            errors,
            size,
            DISPARITY_SCALE,
        )?;
    }
    let json = dir.join("summary.json");
    let text = serde_json::to_string_pretty(summary).expect("the summary serialises");
    std::fs::write(&json, text).map_err(io(&json))
}
