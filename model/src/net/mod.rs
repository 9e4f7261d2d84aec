//! The StereoSplat network (paper section 3.2) in candle: a shared CNN backbone
//! and a monocular geometry encoder, a multi-view transformer, the input-invariant plane-sweep
//! cost volume over each view's nearest views, a U-Net depth head, and per-pixel Gaussian
//! heads, and (when the preset switches it on) the 3D-volume branch of [`volume`]. One
//! [`Config`] holds every size; [`Config::preset`] names them.
//!
//! [`StereoSplat::forward`] returns every Gaussian of each branch with what training needs; [`LearnedReconstructor`] prunes them to what the scene
//! needs (opacity floor, budget, pair fusion, [`merge`] of redundant Gaussians) and implements
//! the project's `Reconstructor`.

pub(crate) mod blocks;
mod census_volume;
mod config;
mod cost_volume;
mod depth_head;
pub mod depth_range;
mod encoders;
mod gaussian_head;
mod geometry;
pub mod guidance;
pub mod hint_fill;
pub mod merge;
pub mod pair_fusion;
pub mod prune;
mod reconstructor;
mod row_correlation;
mod stereosplat;
pub(crate) mod transformer;
pub mod volume;
mod warm_start;

pub use config::{
    apply_settings, weights_preset, Config, SettingError, UnknownPreset, PRESETS, RIG_DEPTH_LIMITS,
};
pub use cost_volume::candidate_depths;
pub use depth_head::normalised_inverse;
pub use reconstructor::{
    default_weights, images_and_cameras, pair_fusion_flags, to_set, to_set_counted, BranchReport,
    LearnedReconstructor, LoadError, Reconstruction,
};
pub use stereosplat::{every_nth_pixel, Prediction, StereoSplat, COST_STRIDE};
pub use warm_start::{frozen, load_matching, WarmStart};
