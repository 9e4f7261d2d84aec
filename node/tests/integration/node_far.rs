//! Far from the world origin: global-map positions must stay exact at 1e5 m from the origin.
//! The same generated drive is sent twice into a fresh in-process node, once as generated and
//! once with every pose translated by (1e5, -1e5, 50) m. The bin maps live in bin frames, so
//! they must not change (f32, to float noise); everything in the world frame must move by
//! exactly the offset: the published bin poses (f64, to 1e-6 m), the exported global map
//! (`global_map.ssgmap`, f64 positions, Gaussian by Gaussian) and its origin
//! (`global_map_origin.json`), while the exported PLY (positions relative to that origin, f32)
//! stays the same.

use crate::drive_support;

use std::path::Path;

use drive_support::{out_file, Collector, Drive, Player, RunningNode};
use glam::{DAffine3, DVec3};
use model::synth::SynthConfig;
use node::fusion::GlobalMap;
use node::msg::gaussians::records_from_cloud;
use node::msg::geometry_msgs::PoseStamped;
use node::msg::pose::affine_from_pose;
use node::msg::sensor_msgs::PointCloud2;
use node::pipeline::worker::RenderWith;
use node::service::NodeConfig;
use node::transport::Keys;

const OFFSET: DVec3 = DVec3::new(1.0e5, -1.0e5, 50.0);

/// What one run published and exported.
struct Run {
    bins_published: u64,
    counters: node::counters::Counters,
    poses: Vec<DAffine3>,
    maps: Vec<PointCloud2>,
    map: GlobalMap,
    origin: DVec3,
    ply: renderer::GaussianSet,
}

async fn run_drive(drive: &Drive, shift: DVec3, out: &Path) -> Run {
    let keys = Keys::new("far");
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        queue_capacity: 64, // never full here: every bin is published
        renders: RenderWith::Off,
        out_dir: Some(out.to_path_buf()),
        ..NodeConfig::default()
    })
    .await;
    let outputs = Collector::connect(&node, &[keys.bin_map(), keys.bin_pose()]).await;
    let player = Player::connect(&node).await;
    player
        .drive(drive, DAffine3::from_translation(shift), 0)
        .await;
    let opened = drive.bins_opened(8.0);
    assert!(outputs.wait_count(&keys.bin_pose(), opened).await);
    let summary = node.stop().await;
    assert_eq!(summary.counters.get("dropped/worker_queue"), 0);
    let origin: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_file(out, "global_map_origin.json")).unwrap())
            .unwrap();
    let axis = |a: &str| origin[a].as_f64().expect("origin coordinate");
    Run {
        bins_published: summary.bins_published,
        counters: summary.counters.clone(),
        poses: outputs
            .decoded::<PoseStamped>(&keys.bin_pose())
            .iter()
            .map(|p| affine_from_pose(p).unwrap())
            .collect(),
        maps: outputs.decoded(&keys.bin_map()),
        map: GlobalMap::load(out_file(out, "global_map.ssgmap")).unwrap(),
        origin: DVec3::new(axis("x"), axis("y"), axis("z")),
        ply: renderer::ply::load_ply(out_file(out, "global_map.ply")).unwrap(),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_drive_1e5_m_out_gives_the_same_bin_maps_and_a_world_map_shifted_exactly() {
    let drive = Drive::generate(
        "far",
        &SynthConfig {
            seed: 11,
            frames: 60,
            width: 136,
            height: 40,
            lidar_azimuth_steps: 64,
            ..SynthConfig::default()
        },
    );
    let opened = drive.bins_opened(8.0);
    assert!(opened >= 4, "{opened} bins");
    let near = run_drive(&drive, DVec3::ZERO, &drive.dir("out_near")).await;
    let far = run_drive(&drive, OFFSET, &drive.dir("out_far")).await;

    for run in [&near, &far] {
        assert_eq!(run.bins_published, opened as u64, "{:?}", run.counters);
        assert_eq!(run.poses.len(), opened);
        assert_eq!(run.maps.len(), opened);
    }

    // Bin poses: translated by exactly the offset, rotations untouched.
    let mut worst_pose = 0.0f64;
    for (a, b) in near.poses.iter().zip(&far.poses) {
        worst_pose = worst_pose.max((b.translation - a.translation - OFFSET).abs().max_element());
        assert!(b.matrix3.abs_diff_eq(a.matrix3, 1e-12), "{a:?} vs {b:?}");
    }
    assert!(worst_pose <= 1e-6, "bin poses off by {worst_pose} m");

    // Bin maps (bin frame, f32): the same Gaussians, value for value.
    let mut worst_map = 0.0f64;
    for (a, b) in near.maps.iter().zip(&far.maps) {
        assert_eq!(a.header.frame_id, b.header.frame_id);
        assert_eq!(a.width, b.width, "{}", a.header.frame_id);
        let (ra, rb) = (
            records_from_cloud(a).unwrap(),
            records_from_cloud(b).unwrap(),
        );
        for (x, y) in ra.iter().zip(&rb) {
            for (u, v) in x.iter().zip(y) {
                worst_map = worst_map.max((u - v).abs());
            }
        }
    }
    assert!(worst_map <= 1e-5, "bin maps differ by up to {worst_map}");

    // The fused world map: the same Gaussians (same ids, same bins), each moved by the
    // offset in f64, the rest unchanged.
    assert!(near.map.len() > 1000, "{} Gaussians", near.map.len());
    assert_eq!(near.map.len(), far.map.len());
    let mut worst_world = 0.0f64;
    for ((ia, a), (ib, b)) in near.map.gaussians().zip(far.map.gaussians()) {
        assert_eq!(ia, ib);
        assert_eq!(a.bin_id, b.bin_id);
        worst_world = worst_world.max((b.position - a.position - OFFSET).abs().max_element());
        assert!(a.rotation.abs_diff_eq(b.rotation, 1e-6), "{ia:?}");
        assert_eq!(
            (a.log_scale, a.opacity, a.color, a.confidence),
            (b.log_scale, b.opacity, b.color, b.confidence),
            "{ia:?}"
        );
    }
    assert!(
        worst_world <= 1e-6,
        "world positions off by {worst_world} m"
    );
    let origin_error = (far.origin - near.origin - OFFSET).abs().max_element();
    assert!(origin_error <= 1e-6, "origin off by {origin_error} m");

    // The PLY holds positions relative to that origin: the same file content near and far.
    assert_eq!(near.ply.len(), far.ply.len());
    let worst_ply = near
        .ply
        .means
        .iter()
        .zip(&far.ply.means)
        .map(|(a, b)| (*a - *b).abs().max_element())
        .fold(0.0f32, f32::max);
    assert!(
        worst_ply <= 1e-4,
        "PLY positions differ by up to {worst_ply} m"
    );
    println!(
        "{opened} bins, {} Gaussians in the world map; largest errors: bin pose {worst_pose:e} m, \
         bin map value {worst_map:e}, world position {worst_world:e} m, origin {origin_error:e} \
         m, PLY position {worst_ply:e} m",
        near.map.len()
    );
}
