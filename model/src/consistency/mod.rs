//! The per-bin self-check: does a reconstruction explain its own stereo pair?
//!
//! Method-agnostic: it needs only the bin's reference stereo pair with its cameras and the
//! [`GaussianSet`] any reconstructor produced. The left image is cut into a sparse grid of
//! cells (at most [`CheckSettings::max_cells`] of them, whatever the image size); the
//! Gaussian centres (opaque enough, in front of the camera) are projected into the left
//! image and each cell keeps its nearest one, a z-buffer of centres. For each cell whose
//! left patch has texture, the kept centre is projected into the right image and the left
//! patch around it is compared with the right patch around its projection by zero-mean
//! normalised cross-correlation (ZNCC: blind to gain and offset between the two cameras).
//! Geometry that is right puts both patches on the same surface, so they correlate; wrong
//! depth compares different surfaces.
//!
//! - `samples`: textured cells that hold a centre; a centre whose right patch falls outside
//!   the right image or behind the camera counts as a failed sample.
//! - `score`: the fraction of samples with ZNCC at least [`CheckSettings::good_zncc`].
//! - `coverage`: samples over textured cells (a reconstruction that leaves most of the
//!   textured image empty does not explain it).
//! - [`Verdict::Undetermined`] when fewer than [`CheckSettings::min_samples`] cells are
//!   textured (a black, white or flat image: nothing can be checked), or when too few
//!   samples remain; [`Verdict::Fail`] when the textured cells explained by a consistent
//!   sample (`score x coverage`) are under [`CheckSettings::pass_score`]. One number judges
//!   dense and sparse maps alike: a dense map of garbage has full coverage and a low score,
//!   and a matcher's sparse map of a wrong pair has a fair score on the few pixels it
//!   matched by chance but low coverage.
//!
//! Cost: one pass over at most [`CheckSettings::max_gaussians`] centres (larger sets are
//! strided) and one pair of 7x7 patches per cell, so it is bounded for any set and image.
//!
//! The thresholds come from the distributions measured with `stereosplat bench check` on
//! generated validation drives (docs/crashes-and-limits.md, "Self-check"): SGM and the
//! shipped `tiny` weights on true pairs against bad pairs (the right image of another drive,
//! left and right swapped, the right image shifted down).

mod patch;

use glam::Vec3;
use renderer::{Camera, GaussianSet};

use crate::reconstruct::StereoView;
use patch::{Grey, Patch};

/// The self-check's settings; [`Default`] holds the chosen thresholds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CheckSettings {
    /// Half the side of the compared patches in pixels (3: 7x7 patches).
    pub patch_radius: usize,
    /// Grid cells at most: the grid's stride grows with the image so the cost stays bounded.
    pub max_cells: usize,
    /// Smallest grid stride in pixels.
    pub min_stride: usize,
    /// Gaussians visited at most; larger sets are strided evenly.
    pub max_gaussians: usize,
    /// Gaussians less opaque than this are not surfaces the images show.
    pub min_opacity: f32,
    /// Smallest standard deviation of a left patch's grey values (image values in [0, 1])
    /// for the patch to count as textured; flatter patches correlate with anything.
    pub min_texture: f32,
    /// ZNCC from which a sample counts as consistent.
    pub good_zncc: f32,
    /// Fewest textured cells (and samples) for a verdict; fewer: undetermined.
    pub min_samples: u32,
    /// Smallest share of textured cells explained by a consistent sample (score x
    /// coverage) that passes.
    pub pass_score: f32,
}

impl Default for CheckSettings {
    /// 7x7 patches, at most 4096 cells of 4 px or more, 2^20 Gaussians, opacity 0.05,
    /// texture 0.02, ZNCC 0.7; at least 32 textured cells, and 60% of them explained by a
    /// consistent sample to pass (chosen on generated validation drives:
    /// docs/crashes-and-limits.md, "Self-check").
    fn default() -> Self {
        Self {
            patch_radius: 3,
            max_cells: 4096,
            min_stride: 4,
            max_gaussians: 1 << 20,
            min_opacity: 0.05,
            min_texture: 0.02,
            good_zncc: 0.7,
            min_samples: 32,
            pass_score: 0.6,
        }
    }
}

/// The self-check's conclusion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Verdict {
    /// The reconstruction explains its stereo pair.
    Pass,
    /// It does not: its geometry disagrees with the pair.
    Fail,
    /// Too little texture to tell (an empty, saturated or flat image).
    Undetermined,
}

impl Verdict {
    /// `pass`, `fail` or `undetermined` (counters, logs).
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Fail => "fail",
            Verdict::Undetermined => "undetermined",
        }
    }
}

/// What the self-check measured on one bin. Every number is finite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CheckReport {
    /// Fraction of samples whose patches correlate (ZNCC >= `good_zncc`), in [0, 1]; 0
    /// without samples.
    pub score: f32,
    /// Samples over textured cells, in [0, 1]; 0 without textured cells.
    pub coverage: f32,
    /// Textured cells holding a Gaussian centre (the samples scored).
    pub samples: u32,
    /// Textured cells of the left image.
    pub textured: u32,
    /// The conclusion.
    pub verdict: Verdict,
}

/// A grid cell's nearest Gaussian centre: depth in the left camera, left pixel, index.
#[derive(Clone, Copy)]
struct Nearest {
    z: f32,
    u: f32,
    v: f32,
    index: usize,
}

/// Pixel coordinates and depth of a bin-local point in `camera`, `None` behind it (or at a
/// non-finite position).
fn project(camera: &Camera, p: Vec3) -> Option<(f32, f32, f32)> {
    const NEAR: f32 = 1e-3;
    let c = camera.rotation * (p - camera.position);
    let k = &camera.intrinsics;
    let (u, v) = (k.fx * c.x / c.z + k.cx, k.fy * c.y / c.z + k.cy);
    (c.z > NEAR && u.is_finite() && v.is_finite()).then_some((u, v, c.z))
}

/// Checks `set` against the stereo pair of `view` (see the module doc).
pub fn check(view: &StereoView<'_>, set: &GaussianSet, s: &CheckSettings) -> CheckReport {
    let r = s.patch_radius;
    let (Some(left), Some(right)) = (Grey::new(view.left, r), Grey::new(view.right, r)) else {
        return report(0, 0, 0, s);
    };
    let (w, h) = (left.width(), left.height());
    let stride = s
        .min_stride
        .max(((w * h) as f64 / s.max_cells.max(1) as f64).sqrt().ceil() as usize)
        .max(1);
    let (gw, gh) = (w.div_ceil(stride), h.div_ceil(stride));
    let cells = nearest_centres(view, set, s, stride, (gw, gh), (w, h));

    let (mut lp, mut rp) = (Patch::default(), Patch::default());
    let (mut textured, mut samples, mut good) = (0u32, 0u32, 0u32);
    for (i, cell) in cells.iter().enumerate() {
        let (ul, vl) = match cell {
            Some(n) => (n.u.round() as i64, n.v.round() as i64),
            None => (
                ((i % gw) * stride + stride / 2) as i64,
                ((i / gw) * stride + stride / 2) as i64,
            ),
        };
        if left.patch_at(ul, vl, r, &mut lp).is_none() || lp.moments().std < s.min_texture {
            continue;
        }
        textured += 1;
        let Some(n) = cell else { continue };
        samples += 1;
        let Some((ur, vr, _)) = project(&view.right_camera, set.means[n.index]) else {
            continue;
        };
        // The left patch sits on the rounded pixel: shift the right one by the same amount.
        let (x, y) = (ur + (ul as f32 - n.u), vr + (vl as f32 - n.v));
        if right.patch_bilinear(x, y, r, &mut rp).is_some() && lp.zncc(&rp) >= s.good_zncc {
            good += 1;
        }
    }
    report(textured, samples, good, s)
}

/// Each grid cell's nearest opaque-enough Gaussian centre in the left image.
fn nearest_centres(
    view: &StereoView<'_>,
    set: &GaussianSet,
    s: &CheckSettings,
    stride: usize,
    (gw, gh): (usize, usize),
    (w, h): (usize, usize),
) -> Vec<Option<Nearest>> {
    let mut cells: Vec<Option<Nearest>> = vec![None; gw * gh];
    let n = set.means.len().min(set.opacities.len());
    let step = n.div_ceil(s.max_gaussians.max(1)).max(1);
    for index in (0..n).step_by(step) {
        let (p, o) = (set.means[index], set.opacities[index]);
        if o.is_nan() || o < s.min_opacity || !p.is_finite() {
            continue;
        }
        let Some((u, v, z)) = project(&view.left_camera, p) else {
            continue;
        };
        if !(u >= 0.0 && v >= 0.0 && u <= (w - 1) as f32 && v <= (h - 1) as f32) {
            continue;
        }
        let (cx, cy) = (u.round() as usize / stride, v.round() as usize / stride);
        let cell = &mut cells[cy.min(gh - 1) * gw + cx.min(gw - 1)];
        if cell.is_none_or(|c| z < c.z) {
            *cell = Some(Nearest { z, u, v, index });
        }
    }
    cells
}

/// The report of `good` consistent samples out of `samples`, over `textured` cells.
fn report(textured: u32, samples: u32, good: u32, s: &CheckSettings) -> CheckReport {
    let ratio = |a: u32, b: u32| if b == 0 { 0.0 } else { a as f32 / b as f32 };
    let (score, coverage) = (ratio(good, samples), ratio(samples, textured));
    // Too few textured cells, or too few samples on a map that covers them: nothing to judge.
    let too_few = samples < s.min_samples && coverage >= s.pass_score;
    let verdict = if textured < s.min_samples || too_few {
        Verdict::Undetermined
    } else if score * coverage < s.pass_score {
        Verdict::Fail
    } else {
        Verdict::Pass
    };
    CheckReport {
        score,
        coverage,
        samples,
        textured,
        verdict,
    }
}

#[cfg(test)]
mod tests;
