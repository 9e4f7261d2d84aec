//! `stereosplat reconstruct`: one stereo pair of image files in (any size, grey or colour,
//! PNG or JPEG), the calibration from flags or ROS camera-info YAML (raw cameras' images
//! rectified by the YAMLs' K, D, R and P, as the node rectifies `image_raw`); a 3DGS PLY,
//! a 16-bit KITTI-convention depth PNG, the same depth as 32-bit floats (`depth.npy`, for
//! scoring without the PNG's 1/256-m steps), a colour-mapped depth PNG, a render and a JSON
//! summary out (see `node::pair::outputs`). With `--truth-disparity` it also scores the
//! disparity against a ground truth (bad-1, bad-3, end-point error, density).

use std::path::{Path, PathBuf};

use super::common::method_args::MethodArgs;
use super::run::OnCheckFailArg;
use crate::pair::calib::CalibrationInput;
use crate::pair::outputs::{write_all, Summary};
use crate::pair::photometric::photometric;
use crate::pair::run::{DEFAULT_WORKING_PIXELS, SURFACE_OPACITY};
use crate::pair::truth::{score, TruthDisparity};
use crate::pair::{images, reconstruct_pair, DepthRule, PairOptions};
use anyhow::{Context, Result};
use clap::Args;
use model::frame::DepthMap;

/// Flags of `reconstruct`.
#[derive(Args, Clone, Debug)]
pub struct ReconstructArgs {
    /// Left (reference) image: rectified, or raw with the raw cameras' --camera-info files.
    #[arg(long)]
    left: PathBuf,
    /// Right image, same size.
    #[arg(long)]
    right: PathBuf,
    /// Focal length along x, pixels of the input images.
    #[arg(long, conflicts_with = "camera_info")]
    fx: Option<f64>,
    /// Focal length along y (default: fx).
    #[arg(long, conflicts_with = "camera_info")]
    fy: Option<f64>,
    /// Principal point x (default: the image centre).
    #[arg(long, conflicts_with = "camera_info")]
    cx: Option<f64>,
    /// Principal point y (default: the image centre).
    #[arg(long, conflicts_with = "camera_info")]
    cy: Option<f64>,
    /// Baseline in metres (or from --camera-info-right).
    #[arg(long)]
    baseline: Option<f64>,
    /// The left camera's ROS camera_calibration YAML. The pair is reconstructed in the
    /// rectified camera of its P; a file with a lens (D), a rotation (R) or a K other than
    /// P's makes the images raw, rectified first (needs --camera-info-right).
    #[arg(long)]
    camera_info: Option<PathBuf>,
    /// The right camera's YAML: its P[0,3] = -fx * baseline gives the baseline.
    #[arg(long)]
    camera_info_right: Option<PathBuf>,
    /// The images are rectified already (`image_rect`): only the YAMLs' P is used, never
    /// their lens.
    #[arg(long, requires = "camera_info")]
    pre_rectified: bool,
    /// Output folder: gaussians.ply, depth.png (16-bit, metres x 256), depth.npy (the same
    /// z-depth as float32 metres, NumPy .npy, height x width, 0 = no depth), depth_color.png,
    /// render.png, the error maps and summary.json.
    #[arg(long, default_value = "out/reconstruct")]
    out: PathBuf,
    #[command(flatten)]
    method: MethodArgs,
    /// Most pixels the reconstructor works at; larger pairs are area-averaged down.
    #[arg(long, default_value_t = DEFAULT_WORKING_PIXELS)]
    working_pixels: u64,
    /// Refuse a pair whose median |vertical disparity| exceeds this many input pixels.
    #[arg(long, default_value_t = PairOptions::default().max_vertical_px)]
    max_vertical_disparity: f32,
    /// Ground-truth disparity of the left image (8- or 16-bit grey PNG, 0 = unknown).
    #[arg(long)]
    truth_disparity: Option<PathBuf>,
    /// Disparity per ground-truth PNG unit (Middlebury 8-bit: 1; KITTI 16-bit: 1/256).
    #[arg(long, default_value_t = 1.0)]
    truth_scale: f32,
    /// What to do when the reconstruction fails the self-check (as the node per bin):
    /// `sgm` writes SGM's reconstruction instead, `lower-opacity` dims it, `flag` keeps it
    /// (the summary says it failed either way).
    #[arg(long, value_enum, default_value_t = OnCheckFailArg::Sgm)]
    on_check_fail: OnCheckFailArg,
    /// The depth a covered pixel gets from the rendering: `surface`, the depth of the
    /// Gaussian that takes the opacity to --surface-opacity (one surface's depth, also at
    /// edges), or `expected`, the opacity-weighted mean (at an edge a blend of both
    /// surfaces).
    #[arg(long, value_enum, default_value_t = DepthRuleArg::Surface)]
    depth: DepthRuleArg,
    /// With --depth surface: the opacity at which a pixel's depth is taken (0.5: the median
    /// depth; a pixel whose opacity stays below it takes the median). Higher passes over the
    /// faint fringe a nearer surface's Gaussians spread over a farther one.
    #[arg(long, default_value_t = SURFACE_OPACITY)]
    surface_opacity: f32,
}

/// [`DepthRule`] on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum DepthRuleArg {
    /// The surface depth at --surface-opacity.
    Surface,
    /// The opacity-weighted expected depth.
    Expected,
}

impl From<DepthRuleArg> for DepthRule {
    fn from(a: DepthRuleArg) -> Self {
        match a {
            DepthRuleArg::Surface => DepthRule::Surface,
            DepthRuleArg::Expected => DepthRule::Expected,
        }
    }
}

/// Runs the reconstruction and writes the outputs.
pub fn run(args: &ReconstructArgs) -> Result<()> {
    let input = CalibrationInput {
        fx: args.fx,
        fy: args.fy,
        cx: args.cx,
        cy: args.cy,
        baseline: args.baseline,
        camera_info: args.camera_info.clone(),
        camera_info_right: args.camera_info_right.clone(),
        pre_rectified: args.pre_rectified,
    };
    let rectifier = input.rectifier()?;
    let (left, right) = images::load_pair(&args.left, &args.right, rectifier.as_ref())?;
    let calib = input.resolve((left.width, left.height))?;
    let truth = args
        .truth_disparity
        .as_deref()
        .map(|path| TruthDisparity::load(path, args.truth_scale))
        .transpose()?;
    let mut reconstructor = args.method.build()?;
    let options = PairOptions {
        working_pixels: args.working_pixels,
        max_vertical_px: args.max_vertical_disparity,
        on_check_fail: args.on_check_fail.into(),
        depth_rule: args.depth.into(),
        surface_opacity: args.surface_opacity,
        ..PairOptions::default()
    };
    let pair = reconstruct_pair(&left, &right, &calib, reconstructor.as_mut(), &options)?;
    let consistency = photometric(&left, &right, &pair.depth, &calib);
    let scored = truth.as_ref().map(|t| score(&pair.depth, &calib, t));
    let summary = Summary::new(
        reconstructor.name(),
        &calib,
        &pair,
        consistency,
        scored.as_ref().map(|(s, _)| s.clone()),
    );
    let truth_errors = scored
        .as_ref()
        .zip(truth.as_ref())
        .map(|((_, e), t)| (e.as_slice(), (t.width, t.height)));
    write_all(&args.out, &pair, &summary, truth_errors)
        .with_context(|| format!("writing into {}", args.out.display()))?;
    let npy = args.out.join("depth.npy");
    save_depth_npy(&npy, &pair.depth).with_context(|| format!("writing {}", npy.display()))?;
    print(&summary);
    println!("wrote {}", args.out.display());
    Ok(())
}

/// `depth.npy`: the left-camera z-depth in metres as a NumPy array (format 1.0,
/// little-endian float32, shape height x width), 0 where there is no depth.
fn save_depth_npy(path: &Path, depth: &DepthMap) -> std::io::Result<()> {
    let dict = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({}, {}), }}",
        depth.height, depth.width
    );
    // Magic (6), version (2) and length (2) before the header, padded with spaces to a
    // multiple of 64 bytes and ended by a newline, as the format asks.
    let padded = (10 + dict.len() + 1).div_ceil(64) * 64 - 10;
    let mut bytes = Vec::with_capacity(10 + padded + 4 * depth.data.len());
    bytes.extend_from_slice(b"\x93NUMPY\x01\x00");
    bytes.extend_from_slice(&(padded as u16).to_le_bytes());
    bytes.extend_from_slice(format!("{dict:<width$}\n", width = padded - 1).as_bytes());
    let finite = |z: f32| if z.is_finite() && z > 0.0 { z } else { 0.0 };
    bytes.extend(depth.data.iter().flat_map(|&z| finite(z).to_le_bytes()));
    std::fs::write(path, bytes)
}

/// Prints the summary's figures, one per line.
fn print(s: &Summary) {
    println!(
        "{}: {}x{} input, worked at {}x{}, {} Gaussians in {:.2} s",
        s.method,
        s.input_size.0,
        s.input_size.1,
        s.working_size.0,
        s.working_size.1,
        s.gaussians,
        s.reconstruct_s
    );
    match s.vertical_input_px {
        Some(v) => println!(
            "vertical disparity: median {v:.2} px over {} patches",
            s.vertical.patches
        ),
        None => println!("vertical disparity: too little texture to measure"),
    }
    let c = &s.check;
    println!(
        "self-check: {} (score {:.3}, coverage {:.3}), action {}{}",
        c.verdict,
        c.score,
        c.coverage,
        c.action,
        c.fallback.map_or(String::new(), |(v, score)| format!(
            ": SGM {v} (score {score:.3})"
        ))
    );
    println!("depth: {:.1}% of pixels", s.depth_density);
    if let Some([p5, p50, p95]) = s.depth_percentiles_m {
        println!("depth percentiles 5/50/95: {p5:.2} / {p50:.2} / {p95:.2} m");
    }
    match s.photometric.mae {
        Some(m) => println!(
            "photometric error: {m:.4} on {:.1}% of pixels",
            100.0 * s.photometric.scored_fraction
        ),
        None => println!("photometric error: no pixel scored"),
    }
    if let Some(t) = &s.truth {
        let epe = t.epe.map_or("n/a".into(), |e| format!("{e:.2} px"));
        println!(
            "disparity vs truth: bad-1 {:.2}%, bad-3 {:.2}% (missing counts wrong), EPE {epe}, \
             density {:.1}%, bad-3 on predicted {:.2}%",
            t.bad1, t.bad3, t.density, t.bad3_predicted
        );
    }
}
