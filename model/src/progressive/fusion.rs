//! Confidence-guided fusion of G_base and G_plus, per Gaussian (what the node publishes).
//!
//! The paper gives no formula. The rule here: G_base is kept whole (it stands on the real
//! pair, the only views that saw the scene); from G_plus only the Gaussians of the pseudo
//! pairs that no earlier view explains are added (pair fusion, the multi-pair rule the
//! reconstructor already uses, judged against the real pair's and earlier pseudo pairs'
//! depth), each with its opacity multiplied by its own confidence, so a pseudo Gaussian
//! the network doubts fades instead of covering the real ones; those that fall below the
//! opacity floor are dropped, and when the budget is short the most opaque additions win.
//! Averaging G_base and G_plus per pixel instead would blur the real pair's Gaussians with
//! guesses drawn from renders of themselves.

use renderer::GaussianSet;

/// How [`fuse`] treats the additions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FuseSettings {
    /// Additions whose weighted opacity is below this (or not finite) are dropped.
    pub floor: f32,
    /// At most this many Gaussians come out in all.
    pub budget: usize,
    /// An addition's opacity is multiplied by its confidence to this power.
    pub confidence_power: f32,
}

/// `base` with the Gaussians of `plus` added, each at opacity times confidence to the
/// settings' power; additions below the floor (or not finite) are dropped, and at most the
/// budget of Gaussians come out in all (`base` first, never cut; the most opaque additions
/// fill what is left).
pub fn fuse(base: &GaussianSet, plus: &GaussianSet, settings: &FuseSettings) -> GaussianSet {
    let FuseSettings {
        floor,
        budget,
        confidence_power,
    } = *settings;
    let weighted =
        |i: usize| plus.opacities[i] * plus.confidences[i].clamp(0.0, 1.0).powf(confidence_power);
    let mut added: Vec<usize> = (0..plus.len())
        .filter(|&i| weighted(i).is_finite() && weighted(i) >= floor)
        .collect();
    let room = budget.saturating_sub(base.len());
    if added.len() > room {
        added.sort_by(|&a, &b| weighted(b).total_cmp(&weighted(a)).then(a.cmp(&b)));
        added.truncate(room);
        added.sort_unstable();
    }
    let mut out = base.clone();
    for i in added {
        let mut g = plus.get(i);
        g.opacity = weighted(i);
        out.push(g);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, Vec3};
    use renderer::Gaussian;

    fn set(opacity_confidence: &[(f32, f32)]) -> GaussianSet {
        let mut s = GaussianSet::default();
        for (i, &(opacity, confidence)) in opacity_confidence.iter().enumerate() {
            s.push(Gaussian {
                mean: Vec3::new(i as f32, 0.0, 5.0),
                log_scale: Vec3::splat(-2.0),
                rotation: Quat::IDENTITY,
                opacity,
                color: Vec3::splat(0.5),
                confidence,
            });
        }
        s
    }

    fn settings(floor: f32, budget: usize, confidence_power: f32) -> FuseSettings {
        FuseSettings {
            floor,
            budget,
            confidence_power,
        }
    }

    #[test]
    fn the_confidence_power_sets_how_fast_doubt_fades_an_addition() {
        let plus = set(&[(0.8, 0.5), (0.8, 0.0)]);
        let none = GaussianSet::default();
        let opacities = |p: f32| fuse(&none, &plus, &settings(0.01, 9, p)).opacities;
        assert_eq!(opacities(0.0), [0.8, 0.8]);
        assert_eq!(opacities(2.0), [0.2]);
    }

    #[test]
    fn base_is_kept_and_additions_are_weighted_by_confidence() {
        let base = set(&[(0.9, 0.1), (0.03, 0.0)]);
        let plus = set(&[
            (1.0, 1.0),
            (0.8, 0.5),
            (1.0, 0.0),
            (0.5, 0.03),
            (f32::NAN, 1.0),
        ]);
        let out = fuse(&base, &plus, &settings(0.02, 100, 1.0));
        // Base untouched, whatever its confidence.
        assert_eq!(out.opacities[..2], [0.9, 0.03]);
        // Added: opacity x confidence; confidence 0 and 0.015 (< floor) and NaN dropped.
        assert_eq!(out.opacities[2..], [1.0, 0.4]);
        assert_eq!(out.means[3], plus.means[1]);
    }

    #[test]
    fn the_budget_cuts_only_additions_keeping_the_most_opaque_in_order() {
        let base = set(&[(0.5, 1.0); 3]);
        let plus = set(&[(0.2, 1.0), (0.9, 1.0), (0.6, 1.0), (0.95, 1.0)]);
        let out = fuse(&base, &plus, &settings(0.0, 5, 1.0));
        assert_eq!(out.len(), 5);
        assert_eq!(out.opacities[3..], [0.9, 0.95]);
        // A base already over budget is not cut, and nothing is added.
        assert_eq!(fuse(&base, &plus, &settings(0.0, 2, 1.0)).len(), 3);
        assert_eq!(
            fuse(
                &GaussianSet::default(),
                &GaussianSet::default(),
                &settings(0.0, 9, 1.0)
            )
            .len(),
            0
        );
    }
}
