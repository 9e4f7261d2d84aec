//! Generated drives shared by commands: written once under a cache folder and reused, and
//! the first sequence of a data root.

use std::path::Path;

use anyhow::{Context, Result};
use model::generate::{scene_sequence_name, write_synthetic};
use model::kitti360::Sequence;
use model::synth::SynthConfig;

use crate::progress;

/// The generated drive of `config` under `root`, written (with a progress bar) unless a
/// sequence of that seed, length and size is already there; returns its name.
pub fn cached_drive(root: &Path, config: &SynthConfig) -> Result<String> {
    let name = scene_sequence_name(config.scene, config.seed);
    let ready = Sequence::open(root, &name).is_ok_and(|s| {
        let k = s.rig().intrinsics;
        s.frames().len() == config.frames as usize && (k.width, k.height) == config.size()
    });
    if !ready {
        let bar = progress::bar(config.frames as usize, "generate");
        write_synthetic(root, config, &mut progress::hook(&bar))?;
        bar.finish_and_clear();
    }
    Ok(name)
}

/// The generated drive of `config` under `root` ([`cached_drive`]), opened.
pub fn cached_sequence(root: &Path, config: &SynthConfig) -> Result<Sequence> {
    let name = cached_drive(root, config)?;
    Ok(Sequence::open(root, &name)?)
}

/// The first sequence under a KITTI-360-layout root.
pub fn first_sequence(root: &Path) -> Result<String> {
    Sequence::list(root)?
        .into_iter()
        .next()
        .with_context(|| format!("no sequence under {}", root.display()))
}
