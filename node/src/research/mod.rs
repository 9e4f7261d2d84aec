//! Research commands: generated data (`synth`, `synth-heldout`), training (`train`,
//! `train-enhancer`, `enhancer-data`, `interpolate-weights`) and evaluation (`eval`,
//! `eval-map`, `eval-enhancer`), grouped under `stereosplat research`; and the fused map's
//! quality on a drive ([`map_quality`]), which `eval-map` and `bench drive` score with.

pub mod enhancer_data;
pub mod eval;
pub mod eval_enhancer;
pub mod eval_map;
pub mod interpolate_weights;
pub mod map_quality;
pub mod synth;
pub mod train;
pub mod train_enhancer;
