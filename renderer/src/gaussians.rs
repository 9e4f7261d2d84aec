//! The Gaussian set: a structure of arrays, the form every stage (network heads, rasterizers,
//! PLY, wire messages) reads without conversion.

use glam::{Quat, Vec3};

use crate::real::Real;

/// One Gaussian, for building sets element by element.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gaussian {
    /// Centre, metres, in the set's frame.
    pub mean: Vec3,
    /// Natural log of the three standard deviations along the rotated axes, metres.
    pub log_scale: Vec3,
    /// Orientation; unit by convention (the rasterizers normalise, and map zero to identity).
    pub rotation: Quat,
    /// Opacity in [0, 1] (the rasterizers clamp to that range).
    pub opacity: f32,
    /// Colour: spherical-harmonics degree 0 already evaluated, linear RGB, nominally [0, 1].
    pub color: Vec3,
    /// How much the producer trusts this Gaussian, [0, 1]; composited like a colour channel.
    pub confidence: f32,
}

/// A set of 3D Gaussians as parallel arrays (all of one length).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GaussianSet {
    /// Centres, metres.
    pub means: Vec<Vec3>,
    /// Log standard deviations, metres.
    pub log_scales: Vec<Vec3>,
    /// Orientations (glam order x, y, z, w).
    pub rotations: Vec<Quat>,
    /// Opacities in [0, 1].
    pub opacities: Vec<f32>,
    /// Linear RGB colours.
    pub colors: Vec<Vec3>,
    /// Confidences in [0, 1].
    pub confidences: Vec<f32>,
}

impl GaussianSet {
    /// An empty set with room for `n` Gaussians.
    pub fn with_capacity(n: usize) -> Self {
        Self {
            means: Vec::with_capacity(n),
            log_scales: Vec::with_capacity(n),
            rotations: Vec::with_capacity(n),
            opacities: Vec::with_capacity(n),
            colors: Vec::with_capacity(n),
            confidences: Vec::with_capacity(n),
        }
    }

    /// Number of Gaussians (the length of `means`; see [`GaussianSet::check_lengths`]).
    pub fn len(&self) -> usize {
        self.means.len()
    }

    /// True when the set holds no Gaussian.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// Appends one Gaussian.
    pub fn push(&mut self, g: Gaussian) {
        self.means.push(g.mean);
        self.log_scales.push(g.log_scale);
        self.rotations.push(g.rotation);
        self.opacities.push(g.opacity);
        self.colors.push(g.color);
        self.confidences.push(g.confidence);
    }

    /// The Gaussian at `i`; panics when out of range, like slice indexing.
    pub fn get(&self, i: usize) -> Gaussian {
        Gaussian {
            mean: self.means[i],
            log_scale: self.log_scales[i],
            rotation: self.rotations[i],
            opacity: self.opacities[i],
            color: self.colors[i],
            confidence: self.confidences[i],
        }
    }

    /// Errors with the offending array's name when the arrays differ in length, so a set
    /// assembled by hand or decoded from a file is checked before anything indexes it.
    pub fn check_lengths(&self) -> Result<(), LengthMismatch> {
        let n = self.means.len();
        let lens = [
            ("log_scales", self.log_scales.len()),
            ("rotations", self.rotations.len()),
            ("opacities", self.opacities.len()),
            ("colors", self.colors.len()),
            ("confidences", self.confidences.len()),
        ];
        match lens.into_iter().find(|&(_, l)| l != n) {
            Some((field, len)) => Err(LengthMismatch {
                field,
                len,
                expected: n,
            }),
            None => Ok(()),
        }
    }

    /// A borrowed `f32` view for the CPU rasterizer; errors when the arrays differ in length.
    pub fn view(&self) -> Result<SplatsView<'_, f32>, LengthMismatch> {
        self.check_lengths()?;
        Ok(SplatsView {
            means: bytemuck::cast_slice(&self.means),
            log_scales: bytemuck::cast_slice(&self.log_scales),
            rotations: bytemuck::cast_slice(&self.rotations),
            opacities: &self.opacities,
            colors: bytemuck::cast_slice(&self.colors),
            confidences: &self.confidences,
        })
    }
}

/// The arrays of a [`GaussianSet`] differ in length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("Gaussian set field `{field}` has {len} entries, `means` has {expected}")]
pub struct LengthMismatch {
    /// The field whose length differs from `means`.
    pub field: &'static str,
    /// Its length.
    pub len: usize,
    /// The length of `means`.
    pub expected: usize,
}

/// Gaussians as borrowed plain arrays in scalar `T`: what the CPU rasterizer reads, so the
/// same code runs on an `f32` [`GaussianSet`] and on `f64` copies for gradient checks.
/// Rotations are quaternions in glam order (x, y, z, w), any norm.
#[derive(Clone, Copy, Debug)]
pub struct SplatsView<'a, T> {
    /// Centres.
    pub means: &'a [[T; 3]],
    /// Log standard deviations.
    pub log_scales: &'a [[T; 3]],
    /// Quaternions (x, y, z, w), not necessarily unit.
    pub rotations: &'a [[T; 4]],
    /// Opacities in [0, 1].
    pub opacities: &'a [T],
    /// Linear RGB colours.
    pub colors: &'a [[T; 3]],
    /// Confidences.
    pub confidences: &'a [T],
}

impl<T: Real> SplatsView<'_, T> {
    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.means.len()
    }

    /// True when there is no Gaussian.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }
}

/// Owned plain arrays in scalar `T`: the `f64` twin of a [`GaussianSet`] that gradient checks
/// perturb one number at a time.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SplatsOwned<T> {
    /// Centres.
    pub means: Vec<[T; 3]>,
    /// Log standard deviations.
    pub log_scales: Vec<[T; 3]>,
    /// Quaternions (x, y, z, w).
    pub rotations: Vec<[T; 4]>,
    /// Opacities.
    pub opacities: Vec<T>,
    /// Colours.
    pub colors: Vec<[T; 3]>,
    /// Confidences.
    pub confidences: Vec<T>,
}

impl<T: Real> SplatsOwned<T> {
    /// Converts an `f32` set.
    pub fn from_set(set: &GaussianSet) -> Self {
        let c = |v: f32| T::c(v as f64);
        Self {
            means: set.means.iter().map(|v| v.to_array().map(c)).collect(),
            log_scales: set.log_scales.iter().map(|v| v.to_array().map(c)).collect(),
            rotations: set.rotations.iter().map(|q| q.to_array().map(c)).collect(),
            opacities: set.opacities.iter().map(|&v| c(v)).collect(),
            colors: set.colors.iter().map(|v| v.to_array().map(c)).collect(),
            confidences: set.confidences.iter().map(|&v| c(v)).collect(),
        }
    }

    /// The borrowed view the rasterizer reads.
    pub fn view(&self) -> SplatsView<'_, T> {
        SplatsView {
            means: &self.means,
            log_scales: &self.log_scales,
            rotations: &self.rotations,
            opacities: &self.opacities,
            colors: &self.colors,
            confidences: &self.confidences,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_field_is_named_in_the_error() {
        let mut set = GaussianSet::default();
        set.push(Gaussian {
            mean: Vec3::ZERO,
            log_scale: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            opacity: 0.5,
            color: Vec3::ONE,
            confidence: 1.0,
        });
        assert!(set.view().is_ok());
        set.confidences.clear();
        let err = set.view().unwrap_err();
        assert_eq!(err.field, "confidences");
        assert_eq!((err.len, err.expected), (0, 1));
    }
}
