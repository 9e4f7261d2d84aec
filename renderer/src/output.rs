//! What a render produces and the settings that shape it.

use crate::real::Real;

/// Settings shared by the CPU and GPU rasterizers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Colour behind all Gaussians, linear RGB.
    pub background: [f32; 3],
    /// Gaussians whose centre is nearer than this (camera z, metres) are culled, as 3DGS
    /// culls at its near plane; it also keeps the perspective Jacobian finite.
    pub near: f32,
    /// Gaussians whose centre is farther than this (camera z, metres) are culled.
    pub far: f32,
    /// The accumulated opacity at which [`RenderOutput::surface_depth`] takes its depth;
    /// 0.5 (the default) makes it the median depth.
    pub surface_opacity: f32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            background: [0.0; 3],
            near: 0.01,
            far: 1.0e10,
            surface_opacity: 0.5,
        }
    }
}

/// The images a render produces, row major, `width * height` pixels (RGB interleaved).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderOutput<T = f32> {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Composited colour with the background behind, RGB interleaved.
    pub rgb: Vec<T>,
    /// Expected depth normalised by alpha (0 where alpha is below [`MIN_DEPTH_ALPHA`]).
    pub depth: Vec<T>,
    /// Expected depth not normalised: sum of blend weight times camera-z of the centre.
    pub depth_raw: Vec<T>,
    /// Accumulated opacity, 1 minus the final transmittance.
    pub alpha: Vec<T>,
    /// Composited confidence, sum of blend weight times confidence (no background).
    pub confidence: Vec<T>,
    /// Surface depth: camera-z of the Gaussian whose blend takes the accumulated opacity to
    /// [`RenderSettings::surface_opacity`], or to one half where the pixel never gets
    /// there; 0 where it stays under one half. One surface's depth, where [`Self::depth`]
    /// at an edge between two surfaces is a blend of both that lies on neither; a higher
    /// opacity passes over the faint fringe a nearer surface's Gaussians spread over a
    /// farther one.
    pub surface_depth: Vec<T>,
}

/// Below this accumulated alpha the normalised depth is reported as 0 rather than a ratio of
/// two tiny numbers.
pub const MIN_DEPTH_ALPHA: f64 = 1e-6;

impl<T: Real> RenderOutput<T> {
    /// An output of the given size filled with zeros (transparent, background not yet added).
    pub fn zeros(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            rgb: vec![T::zero(); 3 * n],
            depth: vec![T::zero(); n],
            depth_raw: vec![T::zero(); n],
            alpha: vec![T::zero(); n],
            confidence: vec![T::zero(); n],
            surface_depth: vec![T::zero(); n],
        }
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}
