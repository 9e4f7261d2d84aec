//! A synthetic drive written in the KITTI-360 layout and read back through the same reader
//! real data goes through: identical bytes for a seed, frames and poses as generated, LiDAR
//! depth that agrees with the exact depth.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use model::frame::Side;
use model::generate::{sequence_name, write_synthetic};
use model::kitti360::{Calibration, Sequence};
use model::synth::{SynthConfig, SynthSequence};

fn config(seed: u64) -> SynthConfig {
    SynthConfig {
        seed,
        frames: 12,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    }
}

fn write(case: &str, seed: u64) -> PathBuf {
    let root = std::env::temp_dir().join(format!("stereosplat-gen-{case}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let mut last = (0, 0);
    write_synthetic(&root, &config(seed), &mut |done, all| last = (done, all)).unwrap();
    assert_eq!(last, (12, 12), "progress reaches the end");
    root
}

/// Every file under `dir` with its bytes, by relative path.
fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(dir).unwrap().to_path_buf();
                out.insert(rel, std::fs::read(&path).unwrap());
            }
        }
    }
    out
}

#[test]
fn a_seed_gives_identical_bytes_and_another_seed_other_bytes() {
    let (a, b, c) = (write("a", 3), write("b", 3), write("c", 4));
    let (fa, fb) = (files(&a), files(&b));
    // 12 frames x (2 images + 1 scan + 2 exact depths) + 2 pose files + 3 timestamp files
    // + 3 calibration files.
    assert_eq!(fa.len(), 12 * 5 + 2 + 3 + 3, "{:?}", fa.keys());
    assert_eq!(fa, fb);
    let fc = files(&c);
    let image = |f: &BTreeMap<PathBuf, Vec<u8>>, seed| {
        f[&PathBuf::from(format!(
            "data_2d_raw/{}/image_00/data_rect/0000000005.png",
            sequence_name(seed)
        ))]
            .clone()
    };
    assert_ne!(image(&fa, 3), image(&fc, 4));
    for d in [a, b, c] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn the_reader_returns_what_the_generator_made() {
    let root = write("read", 5);
    let sequence = Sequence::open(&root, &sequence_name(5)).unwrap();
    let calibration = Calibration::synthetic(136, 40);
    let synth = SynthSequence::new(
        config(5),
        calibration.rig().unwrap(),
        calibration.cam_to_velo,
    );
    assert_eq!(sequence.frames().len(), 12);
    assert_eq!(sequence.rig(), *synth.rig());
    for i in [0usize, 7] {
        let made = synth.frame(i);
        let read = sequence.load_frame(i as u32).unwrap();
        // The PNGs hold the images rounded to 8 bits, exactly; poses come back to the
        // file's 16 digits.
        assert!(
            read.left.to_rgb8() == made.frame.left.to_rgb8(),
            "left image {i}"
        );
        assert!(
            read.right.to_rgb8() == made.frame.right.to_rgb8(),
            "right image {i}"
        );
        let pose_error = (read.left_to_world.to_cols_array().iter())
            .zip(made.frame.left_to_world.to_cols_array())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(pose_error < 1e-9, "{pose_error}");
        // LiDAR depth through the calibration files agrees with the exact depth where both
        // exist (points land on the nearest pixel centre, so compare with a tolerance that
        // covers half a pixel of slope on the road).
        let lidar = sequence.lidar_depth(i as u32, Side::Left).unwrap();
        let mut rel: Vec<f32> = lidar
            .data
            .iter()
            .zip(&made.left_depth.data)
            .filter(|(l, d)| **l > 0.0 && **d > 0.0)
            .map(|(l, d)| (l - d).abs() / d)
            .collect();
        assert!(rel.len() > 500, "{} LiDAR pixels", rel.len());
        rel.sort_by(f32::total_cmp);
        let median = rel[rel.len() / 2];
        assert!(median < 0.03, "median relative LiDAR error {median}");
    }
    let _ = std::fs::remove_dir_all(root);
}
