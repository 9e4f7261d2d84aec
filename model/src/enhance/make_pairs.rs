//! `enhancer-data`: render -> truth pairs made by the project's own StereoSplat on drives in
//! the KITTI-360 layout (paper section 3.3). Each draw picks, from a generator seeded by the
//! run's seed and the draw's number, a bin, a number of input pairs `K ~ U{1..max}` (the
//! bin's first pair and `K - 1` other frames of the bin), and one of the given weights
//! (the shipped ones and earlier checkpoints, for variety); it reconstructs the Gaussians as
//! the node does (`LearnedReconstructor`), renders up to `targets` other frames of the bin
//! (a random side each) on the CPU rasterizer, and writes each render with its alpha,
//! confidence, the bin's first left image (the reference) and the true image.
//! Bounded (stops at `pairs`) and resumable (continues after the last whole draw; draw `d`
//! is the same whenever it runs).

use std::path::{Path, PathBuf};

use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::RenderSettings;

use super::pairs::{append_records, write_pictures, PairPictures, PairRecord, PairSet};
use super::EnhanceError;
use crate::bins::BinConfig;
use crate::frame::Side;
use crate::net::LearnedReconstructor;
use crate::reconstruct::Reconstructor;
use crate::train::{draw_targets, BinInputs, DataRoot, TrainingSet};
use renderer::Raster;

/// StereoSplat weights that make renders, with the label the index records.
pub struct Source {
    /// Short name for `pairs.csv`.
    pub label: String,
    /// The network preset with its settings.
    pub config: crate::net::Config,
    /// The safetensors file.
    pub path: PathBuf,
}

/// Settings of `enhancer-data`.
#[derive(Clone, Debug)]
pub struct DataConfig {
    /// Stop once this many pairs exist.
    pub pairs: usize,
    /// Seed of every draw.
    pub seed: u64,
    /// Most input stereo pairs per draw (K).
    pub max_input_pairs: usize,
    /// Frames rendered per draw.
    pub targets: usize,
    /// Bin cutting.
    pub bins: BinConfig,
}

/// Makes pairs from the drives under `data` into `out` until `cfg.pairs` exist; `progress`
/// gets (pairs written, pairs wanted). Returns how many pairs `out` holds.
pub fn make_pairs(
    data: &Path,
    out: &Path,
    sources: &[Source],
    cfg: &DataConfig,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<usize, EnhanceError> {
    std::fs::create_dir_all(out).map_err(EnhanceError::io(out))?;
    let existing = PairSet::open(out)?;
    let mut count = existing.len();
    let mut draw = existing
        .records()
        .iter()
        .map(|r| r.draw + 1)
        .max()
        .unwrap_or(0);
    if count >= cfg.pairs {
        return Ok(count);
    }
    let root = DataRoot {
        path: data.to_path_buf(),
        bins: cfg.bins,
    };
    let set = TrainingSet::open(&[root], None)?;
    let mut nets = sources
        .iter()
        .map(|s| LearnedReconstructor::load(&s.config, &s.path))
        .collect::<Result<Vec<_>, _>>()?;
    let settings = RenderSettings::default();
    let mut raster = Raster::Cpu;
    while count < cfg.pairs {
        let mut rng = ChaCha8Rng::seed_from_u64(crate::train::mix(cfg.seed, draw as u64));
        let (sequence, bin) = set.bin(rng.random_range(0..set.len()));
        let source = rng.random_range(0..sources.len());
        let frames: Vec<usize> = bin.frames().collect();
        let others = frames.len() - 1;
        let k = rng.random_range(1..=cfg.max_input_pairs.clamp(1, others.max(1)));
        let mut inputs = vec![bin.first];
        inputs.extend(
            sample(&mut rng, others, k - 1)
                .into_iter()
                .map(|i| frames[i + 1]),
        );
        inputs.sort_unstable();
        let chosen = draw_targets(&mut rng, &frames, &inputs, cfg.targets);
        let sides: Vec<Side> = chosen
            .iter()
            .map(|_| match rng.random_bool(0.5) {
                true => Side::Left,
                false => Side::Right,
            })
            .collect();

        let poses = sequence.frames();
        let bin_inputs = BinInputs::load(sequence, &bin, &inputs)?;
        let gaussians = nets[source].reconstruct(&bin_inputs.views())?;
        let reference = &bin_inputs.frames[0].left;
        let mut records = Vec::new();
        for (&i, &side) in chosen.iter().zip(&sides) {
            if count + records.len() >= cfg.pairs {
                break;
            }
            let frame = sequence.load_frame(poses[i].index)?;
            let camera = bin_inputs.camera(&frame, side);
            let r = raster.render(&gaussians, &camera, &settings)?;
            let target = match side {
                Side::Left => &frame.left,
                Side::Right => &frame.right,
            };
            let id = count + records.len();
            write_pictures(
                out,
                id,
                &PairPictures {
                    width: r.width,
                    height: r.height,
                    render: &r.rgb,
                    alpha: &r.alpha,
                    confidence: &r.confidence,
                    reference: &reference.data,
                    target: &target.data,
                },
            )?;
            records.push(PairRecord {
                id,
                draw,
                sequence: sequence.name().to_string(),
                first: poses[bin.first].index,
                target: poses[i].index,
                side: match side {
                    Side::Left => "left".into(),
                    Side::Right => "right".into(),
                },
                input_pairs: inputs.len(),
                weights: sources[source].label.clone(),
            });
        }
        append_records(out, &records)?;
        count += records.len();
        draw += 1;
        progress(count, cfg.pairs);
    }
    Ok(count)
}
