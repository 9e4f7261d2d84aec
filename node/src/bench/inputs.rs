//! `stereosplat bench inputs`: what a robot's camera images cost the input side, per image,
//! as JSON on stdout: decoding JPEG (quality 90 and 75) and PNG `CompressedImage`s, converting
//! `bgr8`, `mono16` and `bayer_rggb8` `Image`s, and rectifying a raw `plumb_bob` camera
//! (building its table, once per calibration, and remapping an image). The image is a
//! generated street frame at `--width` x `--height` (KITTI-360's 1408x376 by default). Each
//! figure is the median, least and largest of `--repeats` runs, in milliseconds; the node
//! pays them only for the frames that open bins.

use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use model::frame::Rgb8Image;
use model::kitti360::Calibration;
use model::synth::{SynthConfig, SynthSequence};
use serde_json::{json, Value};

use crate::msg::compressed::{compressed_image, rgb8_from_compressed, Compression, PixelLimits};
use crate::msg::image::{camera_info, image_with_encoding, rgb8_from_image};
use crate::msg::std_msgs::Header;
use crate::rectify::{CameraModel, RemapTable};

/// Flags of `bench inputs`.
#[derive(Args, Clone, Debug)]
pub struct BenchInputsArgs {
    /// Image width.
    #[arg(long, default_value_t = 1408)]
    width: u32,
    /// Image height.
    #[arg(long, default_value_t = 376)]
    height: u32,
    /// Runs of each step.
    #[arg(long, default_value_t = 20)]
    repeats: usize,
}

/// Median, least and largest of `repeats` runs of `step`, in milliseconds.
fn timed(repeats: usize, mut step: impl FnMut() -> Result<()>) -> Result<Value> {
    let mut ms = Vec::with_capacity(repeats);
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        step()?;
        ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    ms.sort_by(f64::total_cmp);
    Ok(json!({ "median": ms[ms.len() / 2], "min": ms[0], "max": ms[ms.len() - 1] }))
}

/// Runs the benchmark and prints its JSON.
pub fn run(args: &BenchInputsArgs) -> Result<()> {
    anyhow::ensure!(
        args.width >= 2 && args.height >= 2,
        "--width and --height: 2 or more"
    );
    let calibration = Calibration::synthetic(args.width, args.height);
    let rig = calibration.rig().context("the generated rig")?;
    let config = SynthConfig {
        frames: 1,
        width: args.width,
        height: args.height,
        supersample: 1,
        ..SynthConfig::default()
    };
    let frame = SynthSequence::new(config, rig, calibration.cam_to_velo)
        .frame(0)
        .frame;
    let img = Rgb8Image {
        width: frame.left.width,
        height: frame.left.height,
        data: frame.left.to_rgb8(),
    };
    let header = Header::new(0, "camera");
    let limits = PixelLimits::default();
    let mut ms = serde_json::Map::new();
    let mut bytes = serde_json::Map::new();
    for (name, compression) in [
        ("jpeg_q90", Compression::Jpeg { quality: 90 }),
        ("jpeg_q75", Compression::Jpeg { quality: 75 }),
        ("png", Compression::Png),
    ] {
        let msg = compressed_image(&img, compression, header.clone())?;
        bytes.insert(name.into(), json!(msg.data.len()));
        let decode = || {
            rgb8_from_compressed(&msg, &limits)
                .map(drop)
                .map_err(Into::into)
        };
        ms.insert(format!("{name}_decode"), timed(args.repeats, decode)?);
    }
    for encoding in ["bgr8", "mono16", "bayer_rggb8"] {
        let msg = image_with_encoding(&img, encoding, header.clone())?;
        let convert = || rgb8_from_image(msg.clone()).map(drop).map_err(Into::into);
        ms.insert(format!("{encoding}_convert"), timed(args.repeats, convert)?);
    }
    // A raw camera behind a plumb_bob lens, rotated half a degree before rectification.
    let mut info = camera_info(&rig.intrinsics, 0.0, header);
    info.d = vec![-0.12, 0.02, 0.0004, -0.0003, 0.0];
    info.r = glam::DMat3::from_rotation_y(0.5f64.to_radians())
        .transpose()
        .to_cols_array();
    let camera = CameraModel::from_camera_info(&info)?;
    let build = || {
        RemapTable::rectify(&camera);
        Ok(())
    };
    ms.insert("rectify_table_build".into(), timed(args.repeats, build)?);
    let table = RemapTable::rectify(&camera);
    let remap = || table.remap(&img).map(drop).map_err(Into::into);
    ms.insert("rectify_remap".into(), timed(args.repeats, remap)?);
    let report = json!({
        "width": args.width,
        "height": args.height,
        "repeats": args.repeats,
        "threads": rayon::current_num_threads(),
        "ms": ms,
        "compressed_bytes": bytes,
    });
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}
