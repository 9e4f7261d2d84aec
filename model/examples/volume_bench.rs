//! Milliseconds of the volume branch's Gaussian side at a preset (default `tiny`), as one
//! JSON line on stdout: projection-guided fusion of a real cost-volume prediction, the
//! occupancy grid, the frustum mask, the top-k selection and the voxel decoder, each the
//! median over timed runs, and their sum; with the cost-volume branch's own time on the
//! same pair for scale. The pair is frame 0 of a generated drive at 544x112, the cost-volume
//! network the shipped weights (untrained if absent). The planes are random (the encoder is
//! not part of this measurement) and the heads untrained, which changes no shape or count.
//!
//! `cargo run --release --example volume_bench -- [PRESET] [RUNS]`

use std::collections::HashMap;
use std::time::Instant;

use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use model::frame::Side;
use model::kitti360::Calibration;
use model::net::volume::{
    frustum_mask, gaussian_rows, top_k, OccupancyHead, ProjectionFusion, VoxelDecoder,
};
use model::net::{default_weights, images_and_cameras, Config, LearnedReconstructor};
use model::reconstruct::StereoView;
use model::synth::{SynthConfig, SynthSequence};

/// Median of `f`'s milliseconds over `runs` runs after one untimed run; `f`'s last result.
fn timed<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut out = f();
    let mut times = Vec::with_capacity(runs);
    for _ in 0..runs {
        let start = Instant::now();
        out = f();
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], out)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let preset = args.next().unwrap_or_else(|| "tiny".into());
    let runs: usize = args.next().map_or(Ok(10), |r| r.parse())?;
    let cfg = Config::preset(&preset)?;
    let vol = cfg.volume.clone();
    let device = Device::Cpu;

    let (width, height) = (544, 112);
    let calibration = Calibration::synthetic(width, height);
    let rig = calibration.rig()?;
    let synth = SynthConfig {
        frames: 2,
        width,
        height,
        ..SynthConfig::default()
    };
    let frame = SynthSequence::new(synth, rig, calibration.cam_to_velo)
        .frame(0)
        .frame;
    let pose = frame.left_to_world;
    let view = StereoView {
        left: &frame.left,
        right: &frame.right,
        left_camera: rig.local_camera(pose, pose, Side::Left),
        right_camera: rig.local_camera(pose, pose, Side::Right),
    };
    let (images, cameras) = images_and_cameras(&[view], &device)?;
    let weights = default_weights(&preset);
    let rec = match weights.exists() {
        true => LearnedReconstructor::load(&cfg, &weights)?,
        false => LearnedReconstructor::untrained(&cfg)?,
    };
    let (cost_volume_ms, prediction) = timed(runs, || rec.net().forward(&images, &cameras));
    let prediction = prediction?;
    let means = prediction.splats.means.clone();
    let k = prediction.features.dim(1)?;

    // Untrained heads as plain tensors (no gradient tracking: the inference path).
    let varmap = VarMap::new();
    let vb = VarBuilder::from_varmap(&varmap, DType::F32, &device);
    ProjectionFusion::new(vb.pp("fusion"), &vol, k)?;
    OccupancyHead::new(vb.pp("occupancy"), &vol)?;
    VoxelDecoder::new(vb.pp("decoder"), &vol)?;
    let frozen: HashMap<String, Tensor> = varmap
        .data()
        .lock()
        .map_err(|_| "the variable map is poisoned")?
        .iter()
        .map(|(k, v)| (k.clone(), v.as_tensor().detach()))
        .collect();
    let vb = VarBuilder::from_tensors(frozen, DType::F32, &device);
    let fusion = ProjectionFusion::new(vb.pp("fusion"), &vol, k)?;
    let occupancy = OccupancyHead::new(vb.pp("occupancy"), &vol)?;
    let decoder = VoxelDecoder::new(vb.pp("decoder"), &vol)?;
    let queries = vol
        .plane_shapes()
        .map(|(rows, cols)| Tensor::randn(0f32, 1.0, (vol.channels, rows, cols), &device));

    let (rows_ms, rows) = timed(runs, || gaussian_rows(&prediction.features));
    let rows = rows?;
    let (pool_ms, prior) = timed(runs, || fusion.forward(&means, &rows));
    let fusion_ms = rows_ms + pool_ms;
    let prior = prior?;
    let mut planes = Vec::with_capacity(3);
    for (q, p) in queries.into_iter().zip(prior.iter()) {
        planes.push((q? + p)?);
    }
    let planes: [Tensor; 3] = [planes[0].clone(), planes[1].clone(), planes[2].clone()];
    let (occupancy_ms, logits) = timed(runs, || occupancy.forward(&planes));
    let logits = logits?;
    let (mask_ms, visible) = timed(runs, || frustum_mask(&vol, &cameras));
    let (top_k_ms, voxels) = timed(runs, || top_k(&logits, &visible, vol.top_k));
    let voxels = voxels?;
    let (decode_ms, splats) = timed(runs, || decoder.forward(&planes, &logits, &voxels));
    let splats = splats?;

    let landed = means
        .to_vec2::<f32>()?
        .iter()
        .filter(|p| vol.cell_of([p[0], p[1], p[2]]).is_some())
        .count();
    let report = serde_json::json!({
        "preset": preset,
        "cost_volume_weights": if weights.exists() { weights.display().to_string() } else { "untrained".into() },
        "width": width,
        "height": height,
        "threads": rayon::current_num_threads(),
        "cells": vol.cells,
        "channels": vol.channels,
        "top_k": vol.top_k,
        "gaussians_per_voxel": vol.gaussians_per_voxel,
        "runs": runs,
        "cost_volume_gaussians": means.dim(0)?,
        "cost_volume_gaussians_in_volume": landed,
        "visible_voxels": visible.iter().filter(|&&s| s).count(),
        "decoded_voxels": voxels.len(),
        "volume_gaussians": splats.means.dim(0)?,
        "cost_volume_ms": cost_volume_ms,
        "fusion_ms": fusion_ms,
        "fusion_feature_rows_ms": rows_ms,
        "occupancy_ms": occupancy_ms,
        "frustum_mask_ms": mask_ms,
        "top_k_ms": top_k_ms,
        "decode_ms": decode_ms,
        "volume_gaussian_side_ms": fusion_ms + occupancy_ms + mask_ms + top_k_ms + decode_ms,
    });
    println!("{report}");
    Ok(())
}
