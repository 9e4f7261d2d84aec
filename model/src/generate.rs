//! Writes synthetic sequences in the KITTI-360 layout, so every consumer (evaluation,
//! training, replay) reads generated and real data through the same
//! [`crate::kitti360::Sequence`]. Seeds are split three ways: training below
//! [`HELDOUT_SEED_BASE`], held-out evaluation from it, validation (where every setting,
//! threshold and checkpoint is chosen) from [`VALIDATION_SEED_BASE`].

use std::path::Path;

use glam::{DAffine3, DMat3, DVec3};

use crate::frame::Side;
use crate::kitti360::{Calibration, Kitti360Error, SequenceWriter};
use crate::synth::{SceneKind, SynthConfig, SynthConfigError, SynthSequence};

/// Seeds from here up are reserved for held-out sequences: training data never uses them,
/// so an evaluation on them measures generalisation to streets never seen.
pub const HELDOUT_SEED_BASE: u64 = 1_000_000;

/// Seeds from here up are validation sequences: disjoint from training (below
/// [`HELDOUT_SEED_BASE`]) and from held-out evaluation (`HELDOUT_SEED_BASE` up to here), so
/// choices made on them are scored on neither.
pub const VALIDATION_SEED_BASE: u64 = 2_000_000;

/// Why a synthetic sequence could not be written.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// The configuration asks for something no camera has.
    #[error("bad synthetic configuration")]
    Config(#[from] SynthConfigError),
    /// Writing the layout failed.
    #[error(transparent)]
    Kitti360(#[from] Kitti360Error),
}

/// The sequence name a street seed is written under, shaped like KITTI-360's names.
pub fn sequence_name(seed: u64) -> String {
    scene_sequence_name(SceneKind::Street, seed)
}

/// The sequence name of seed `seed` of `kind`: `synth_drive_SEED_sync` for streets,
/// `synth_desk_SEED_sync` and `synth_room_SEED_sync` for the indoor kinds.
pub fn scene_sequence_name(kind: SceneKind, seed: u64) -> String {
    let word = match kind {
        SceneKind::Street => "drive",
        other => other.name(),
    };
    format!("synth_{word}_{seed:07}_sync")
}

/// Camera 0 to velodyne for handheld rigs: the scanner 4 cm above the left camera, its
/// rings (+2 to -24.9 degrees) centred on the optical axis, so its sweep covers the middle
/// of the image as a depth sensor beside the camera would (a street's scanner sits 0.8 m
/// behind the camera, outside any room).
pub fn handheld_cam_to_velo() -> DAffine3 {
    let centre =
        (0.5 * (crate::synth::TOP_ELEVATION + crate::synth::BOTTOM_ELEVATION)).to_radians();
    let (c, s) = (centre.cos(), centre.sin());
    // Columns: camera x (right), y (down), z (forward) in velodyne axes (x forward, y left,
    // z up), the optical axis pitched to the rings' middle elevation.
    let forward = DVec3::new(c, 0.0, s);
    let right = DVec3::new(0.0, -1.0, 0.0);
    let down = forward.cross(right);
    DAffine3::from_mat3_translation(
        DMat3::from_cols(right, down, forward),
        DVec3::new(0.0, 0.0, -0.04),
    )
}

/// The calibration a sequence of `config` is written with: KITTI-360's for a plain street,
/// else a rig of the chosen or drawn focal length and baseline (on a handheld mounting for
/// desks and rooms).
pub fn calibration(config: &SynthConfig) -> Calibration {
    let size = config.size();
    let mut calibration = match config.chosen_rig() {
        Some((focal, baseline)) => Calibration::synthetic_rig(size, focal, baseline),
        None => Calibration::synthetic(size.0, size.1),
    };
    if config.scene != SceneKind::Street {
        calibration.cam_to_velo = handheld_cam_to_velo();
    }
    calibration
}

/// Generates the sequence `config` describes and writes it under `root` (images, poses,
/// timestamps, calibration, LiDAR scans, and both cameras' exact depth). `progress` is
/// called after each frame with (frames done, frames in all). Returns the sequence name.
pub fn write_synthetic(
    root: &Path,
    config: &SynthConfig,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<String, GenerateError> {
    config.validate()?;
    let calibration = calibration(config);
    let rig = calibration.rig()?;
    let sequence = SynthSequence::new(*config, rig, calibration.cam_to_velo);
    let name = scene_sequence_name(config.scene, config.seed);
    let mut writer = SequenceWriter::create(root, &name, &calibration)?;
    for i in 0..sequence.len() {
        let frame = sequence.frame(i);
        let t = sequence.timestamp_ns(i);
        writer.write_frame(&frame.frame, t)?;
        writer.write_lidar(frame.frame.index, &frame.lidar, t)?;
        writer.write_exact_depth(frame.frame.index, Side::Left, &frame.left_depth)?;
        writer.write_exact_depth(frame.frame.index, Side::Right, &frame.right_depth)?;
        progress(i + 1, sequence.len());
    }
    writer.finish()?;
    Ok(name)
}
