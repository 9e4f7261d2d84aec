//! The synthetic street generator: determinism, exact depth, stereo and LiDAR consistency,
//! trajectory shape, scene content and image statistics.

use model::synth::{default_cam_to_velo, kitti360_rig, SynthConfig, SynthSequence};

fn sequence(seed: u64, frames: u32, width: u32, height: u32) -> SynthSequence {
    let config = SynthConfig {
        seed,
        frames,
        width,
        height,
        ..SynthConfig::default()
    };
    SynthSequence::new(config, kitti360_rig(width, height), default_cam_to_velo())
}

#[test]
fn preview_pngs() {
    let seq = sequence(3, 200, 544, 144);
    for i in [0usize, 60, 150] {
        let t = std::time::Instant::now();
        let f = seq.frame(i);
        eprintln!("frame {i}: {:?}, lidar {}", t.elapsed(), f.lidar.len());
        for (name, img) in [("left", &f.frame.left), ("right", &f.frame.right)] {
            image::save_buffer(
                format!("/tmp/synth_{name}_{i}.png"),
                &img.to_rgb8(),
                img.width,
                img.height,
                image::ColorType::Rgb8,
            )
            .unwrap();
        }
    }
}
