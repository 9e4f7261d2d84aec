//! Writes synthetic drives in the KITTI-360 layout, so every consumer (evaluation, training,
//! replay) reads generated and real data through the same [`crate::kitti360::Sequence`].

use std::path::Path;

use crate::frame::Side;
use crate::kitti360::{Calibration, Kitti360Error, SequenceWriter};
use crate::synth::{SynthConfig, SynthSequence};

/// Seeds from here up are reserved for held-out sequences: training data never uses them,
/// so an evaluation on them measures generalisation to streets never seen.
pub const HELDOUT_SEED_BASE: u64 = 1_000_000;

/// Seeds from here up are validation sequences: every setting, threshold, blend and
/// checkpoint is chosen on them, so neither training (seeds below [`HELDOUT_SEED_BASE`]) nor
/// the held-out evaluation (from [`HELDOUT_SEED_BASE`] up to here) is scored on what it was
/// tuned on.
pub const VALIDATION_SEED_BASE: u64 = 2_000_000;

/// The sequence name a seed is written under, shaped like KITTI-360's names.
pub fn sequence_name(seed: u64) -> String {
    format!("synth_drive_{seed:07}_sync")
}

/// Generates the drive `config` describes and writes it under `root` (images, poses,
/// timestamps, calibration, LiDAR scans, and both cameras' exact depth). `progress` is called after each frame with (frames
/// done, frames in all). Returns the sequence name.
pub fn write_synthetic(
    root: &Path,
    config: &SynthConfig,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<String, Kitti360Error> {
    let calibration = match config.look() {
        Some(look) => Calibration::synthetic_rig(look.size, look.focal_px, look.baseline_m),
        None => Calibration::synthetic(config.width, config.height),
    };
    let rig = calibration.rig()?;
    let sequence = SynthSequence::new(*config, rig, calibration.cam_to_velo);
    let name = sequence_name(config.seed);
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
