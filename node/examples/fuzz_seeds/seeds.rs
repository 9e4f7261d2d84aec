//! The seed inputs of the decoders' entry points (`node::untrusted_input`): for each entry, a
//! few valid inputs made by the project's own encoders, so fuzzing and the mutation test
//! start from what the decoders really see and mutate outward. Shared by the `fuzz_seeds`
//! example (the fuzz corpus) and the test suite (`decoders_mutated`); the camera images'
//! seeds are in `image_seeds.rs`, those of the robot-side pose sources (Odometry, Path, tf
//! streams) in `robot_seeds.rs`, those of the entries that need the `runtime` feature in
//! `live_seeds.rs`.

use std::path::{Path, PathBuf};

use glam::{DAffine3, DQuat, DVec3};
use model::frame::RgbImage;
use model::kitti360::poses::{write_pose_file, PoseFormat};
use model::kitti360::timestamps::write_timestamps;
use model::kitti360::{layout, Calibration};
use node::bag::{BagWriter, ChannelInfo, CDR};
use node::fusion::{
    segment_path, tile_path, write_tile, FusionConfig, GlobalMap, JournalWriter, PageEvent,
};
use node::msg::gaussians::cloud_from_gaussians;
use node::msg::image::{camera_info, image_from_rgb, rgb8_from_image};
use node::msg::latency::{BinLatency, Counter, Diagnostics};
use node::msg::map_update::MapUpdate;
use node::msg::pose::pose_from_affine;
use node::msg::schema::ros2msg;
use node::msg::std_msgs::Header;
use node::msg::tf2_msgs::{world_to, TfMessage};
use node::msg::{Message, MessageKind};
use node::untrusted_input::join_frames;
use renderer::formats::{write_map, MapFormat};
use renderer::{scene, GaussianSet, Intrinsics};

#[path = "image_seeds.rs"]
mod image_seeds;
#[cfg(feature = "runtime")]
#[path = "live_seeds.rs"]
mod live_seeds;
#[path = "robot_seeds.rs"]
mod robot_seeds;

/// A stamp in 2023, nanoseconds.
pub const STAMP: i64 = 1_700_000_000_250_000_000;

/// Writes every seed as `out/<entry>/<seed>` (a scratch folder `out/scratch` is made and
/// removed on the way).
pub fn write_all(out: &Path) -> anyhow::Result<()> {
    let out = out.to_path_buf();
    let k = Intrinsics {
        fx: 552.5,
        fy: 551.25,
        cx: 4.5,
        cy: 2.5,
        width: 10,
        height: 6,
    };
    let gaussians = scene::random_in_view(7, 3, &k);
    let image = image_from_rgb(&rgb(k.width, k.height), Header::new(STAMP, "cam_left"));
    let pose = DAffine3::from_rotation_translation(
        DQuat::from_axis_angle(DVec3::new(0.2, 1.0, -0.1).normalize(), 0.7),
        DVec3::new(1.0e5, -2.5e5, 31.25),
    );

    let seeds = Seeds(out);
    image_seeds::write(&seeds, &rgb8_from_image(image.clone())?)?;
    for (name, baseline) in [("left", 0.0), ("right", 0.6)] {
        let info = camera_info(&k, baseline, Header::new(STAMP, "cam"));
        seeds.put("cdr_camera_info", name, &info.encode())?;
    }
    let pose_msg = pose_from_affine(&pose, Header::new(STAMP, "world"));
    seeds.put("cdr_pose", "far", &pose_msg.encode())?;
    let tf = TfMessage {
        transforms: vec![
            world_to("bin_3", &pose, STAMP),
            world_to("left", &DAffine3::IDENTITY, STAMP),
        ],
    };
    seeds.put("cdr_tf", "two", &tf.encode())?;
    seeds.put("cdr_tf", "empty", &TfMessage::default().encode())?;
    robot_seeds::write(&seeds, pose)?;
    let bin_cloud = cloud_from_gaussians(&gaussians, Header::new(STAMP, "bin_3"), None)?;
    seeds.put("cdr_point_cloud", "bin", &bin_cloud.encode())?;
    seeds.put(
        "cdr_map_update",
        "increment",
        &map_update(&gaussians)?.encode(),
    )?;
    seeds.put("cdr_latency", "bin_latency", &bin_latency().encode())?;
    seeds.put("cdr_latency", "diagnostics", &diagnostics().encode())?;
    let bag = bag(&seeds.0, &[&image.encode(), &pose_msg.encode()])?;
    // Cut in the middle of its last chunk, as a recorder killed with -9 leaves it (`mcap`
    // recovers it as `replay --mcap` does).
    let cut = &bag[..cut_in_last_chunk(&bag)];
    for target in ["mcap", "mcap_recover"] {
        seeds.put(target, "bag", &bag)?;
        seeds.put(target, "cut", cut)?;
    }
    seeds.put("ply", "binary", &ply(&gaussians)?)?;
    for format in [MapFormat::Spz, MapFormat::Glb] {
        let mut bytes = Vec::new();
        write_map(&gaussians, format, &mut bytes)?;
        seeds.put(format.extension(), "two", &bytes)?;
        bytes.clear();
        write_map(&GaussianSet::default(), format, &mut bytes)?;
        seeds.put(format.extension(), "empty", &bytes)?;
    }
    let mut map = GlobalMap::new(FusionConfig::default())?;
    map.insert_bin(2, &gaussians, pose)?;
    let path = seeds.0.join("scratch").join("global_map.ssgmap");
    map.save(&path)?;
    seeds.put("global_map", "two_bins", &std::fs::read(&path)?)?;
    journal(&seeds, &gaussians, pose)?;
    #[cfg(feature = "runtime")]
    live_seeds::write(&seeds, &k, &gaussians, pose)?;
    seeds.put("ply", "ascii", ASCII_PLY.as_bytes())?;
    seeds.put("kitti_calibration", "synthetic", &calibration(&seeds.0)?)?;
    for (name, format) in [
        ("poses", PoseFormat::ThreeByFour),
        ("cam0_to_world", PoseFormat::FourByFour),
    ] {
        let path = seeds.0.join("scratch").join(name);
        write_pose_file(&path, format, &[(0, DAffine3::IDENTITY), (3, pose)])?;
        seeds.put("kitti_poses", name, &std::fs::read(&path)?)?;
    }
    let path = seeds.0.join("scratch").join("timestamps.txt");
    write_timestamps(&path, &[STAMP, STAMP + 100_000_000])?;
    seeds.put("kitti_timestamps", "two", &std::fs::read(&path)?)?;
    for entry in std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch"))? {
        let path = entry?.path();
        let name = path.file_stem().unwrap_or_default().to_string_lossy();
        seeds.put("launch", &name, &std::fs::read(&path)?)?;
    }
    std::fs::remove_dir_all(seeds.0.join("scratch"))?;
    Ok(())
}

/// The output directory.
pub struct Seeds(PathBuf);

impl Seeds {
    /// Writes seed `name` of `target`.
    pub fn put(&self, target: &str, name: &str, bytes: &[u8]) -> std::io::Result<()> {
        let dir = self.0.join(target);
        std::fs::create_dir_all(&dir)?;
        std::fs::write(dir.join(name), bytes)
    }
}

/// A small image with a different value in every channel.
pub fn rgb(width: u32, height: u32) -> RgbImage {
    let bytes: Vec<u8> = (0..3 * width * height).map(|i| (i * 7) as u8).collect();
    RgbImage::from_rgb8(width, height, &bytes)
}

/// An increment adding `gaussians` (world frame, 100 km out) from bin 2.
fn map_update(gaussians: &GaussianSet) -> anyhow::Result<MapUpdate> {
    let origin = DVec3::new(1.0e5, -2.5e5, 31.25);
    let header = Header::new(STAMP, "world");
    let n = gaussians.len() as u64;
    Ok(MapUpdate {
        header: header.clone(),
        sequence: 3,
        snapshot: false,
        bin_id: 2,
        ids: (10..10 + n).collect(),
        source_bins: vec![2; n as usize],
        removed_ids: vec![4, 5],
        gaussians: cloud_from_gaussians(gaussians, header, Some(origin))?,
    })
}

/// A bin's latency stamps, increasing through the stages.
fn bin_latency() -> BinLatency {
    BinLatency {
        bin_id: 4,
        first_frame_arrival_ns: STAMP,
        bin_close_ns: STAMP + 1_000_000_000,
        model_start_ns: STAMP + 1_010_000_000,
        model_end_ns: STAMP + 1_200_000_000,
        render_end_ns: STAMP + 1_250_000_000,
        publish_ns: STAMP + 1_260_000_000,
        queue_depth: 1,
        drops: 0,
        bad_messages: 2,
        check_verdict: 1,
        check_action: 0,
        fallback_verdict: 0,
        check_samples: 900,
        check_score: 0.93,
        fallback_score: 0.0,
        ..BinLatency::default()
    }
}

/// Two counters.
fn diagnostics() -> Diagnostics {
    let counter = |kind: &str, count| Counter {
        kind: kind.into(),
        count,
    };
    Diagnostics {
        stamp_ns: STAMP,
        counters: vec![
            counter("bad_message/left_image", 2),
            counter("sync/late", 1),
        ],
    }
}

/// Journals as a node writes them, in the `journal_segment` entry's input form (the
/// segment, then each tile file with its version): one bin, and three bins with a tile of
/// the first paged out after the second (far away) and back in before the third (back
/// near the first); and that tile's file alone (`tile_file`).
fn journal(seeds: &Seeds, gaussians: &GaussianSet, pose: DAffine3) -> anyhow::Result<()> {
    let dir = seeds.0.join("scratch").join("journal_seed");
    let (journal, tiles) = (dir.join("journal"), dir.join("tiles"));
    let mut map = GlobalMap::new(FusionConfig::default())?;
    let mut writer = JournalWriter::new(&journal);
    let inc = map.insert_bin(1, gaussians, pose)?;
    writer.append(&map, &inc, &[], &[])?;
    // The segment is named after its first record's sequence number, 1.
    let segment = segment_path(&journal, 1);
    seeds.put(
        "journal_segment",
        "one_bin",
        &join_frames(&[&std::fs::read(&segment)?]),
    )?;
    let far = DAffine3::from_translation(DVec3::new(2.0e3, 0.0, 0.0)) * pose;
    let inc = map.insert_bin(2, gaussians, far)?;
    // The first bin's tiles come first (smaller x); page one out as the node does after a bin.
    let tile = *map
        .resident_tiles()
        .keys()
        .next()
        .ok_or_else(|| anyhow::anyhow!("tiles in memory"))?;
    let version = map.increments();
    let out = map.take_tile(tile, version).map_err(anyhow::Error::msg)?;
    write_tile(&tiles, tile, version, &out)?;
    let paged = map.paged_tiles()[&tile];
    writer.append(&map, &inc, &[], &[PageEvent::Out(tile, paged)])?;
    map.page_in(&tiles, tile)?;
    let inc = map.insert_bin(3, gaussians, pose)?;
    writer.append(&map, &inc, &[PageEvent::In(tile, paged)], &[])?;
    writer.close_segment()?;
    let tile_file = std::fs::read(tile_path(&tiles, tile, version))?;
    let versioned = [&version.to_le_bytes()[..], &tile_file].concat();
    let paged_input = join_frames(&[&std::fs::read(&segment)?, &versioned]);
    seeds.put("journal_segment", "paged", &paged_input)?;
    seeds.put("tile_file", "one", &tile_file)?;
    Ok(())
}

/// An MCAP file holding `payloads[0]` on an image channel and `payloads[1]` on a pose
/// channel, twice each (a chunk each time), as `BagWriter` writes it.
fn bag(dir: &Path, payloads: &[&[u8]; 2]) -> anyhow::Result<Vec<u8>> {
    let channel = |topic: &str, kind: MessageKind| ChannelInfo {
        topic: topic.into(),
        schema_name: kind.ros_name().into(),
        schema_text: ros2msg(kind),
        message_encoding: CDR.into(),
        offered_qos: String::new(),
    };
    let channels = [
        channel("/stereo/left/image_raw", MessageKind::Image),
        channel("/stereo/pose", MessageKind::PoseStamped),
    ];
    let path = dir.join("scratch").join("bag.mcap");
    std::fs::create_dir_all(dir.join("scratch"))?;
    let mut bag = BagWriter::create(&path)?;
    for (i, t) in [0u64, 100_000_000].into_iter().enumerate() {
        for (channel, payload) in channels.iter().zip(payloads) {
            let time = STAMP as u64 + t;
            bag.write(channel, time, time, i as u32, payload)?;
        }
        // One chunk per instant, as a recorder closes one every second.
        bag.flush()?;
    }
    bag.finish()?;
    Ok(std::fs::read(&path)?)
}

/// The byte halfway through the last chunk record of the MCAP file `bag` (its data section's
/// records walked from the start: opcode, u64 length, body).
fn cut_in_last_chunk(bag: &[u8]) -> usize {
    const CHUNK: u8 = 0x06;
    let (mut at, mut cut) = (8, bag.len() / 2);
    while at + 9 <= bag.len() {
        let len = u64::from_le_bytes(bag[at + 1..at + 9].try_into().unwrap_or_default()) as usize;
        if bag[at] == CHUNK {
            cut = at + (9 + len) / 2;
        }
        at = at.saturating_add(9).saturating_add(len);
    }
    cut
}

/// `gaussians` as a binary 3DGS PLY.
fn ply(gaussians: &GaussianSet) -> anyhow::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    renderer::ply::write_ply(gaussians, &mut bytes)?;
    Ok(bytes)
}

/// One Gaussian in the ASCII PLY form (the reader takes both).
const ASCII_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 1\n\
property float x\nproperty float y\nproperty float z\n\
property float nx\nproperty float ny\nproperty float nz\n\
property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n\
property float opacity\n\
property float scale_0\nproperty float scale_1\nproperty float scale_2\n\
property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\n\
end_header\n\
0.5 -1 10 0 0 0 0.2 0.1 -0.3 1.5 -3 -2.5 -4 1 0 0 0\n";

/// The three calibration files of the synthetic calibration, joined by NULs (the
/// `kitti_calibration` target's input form).
fn calibration(dir: &Path) -> anyhow::Result<Vec<u8>> {
    let root = dir.join("scratch");
    Calibration::synthetic(544, 112).write(&root)?;
    let mut joined = Vec::new();
    for path in [
        layout::perspective(&root),
        layout::cam_to_pose(&root),
        layout::cam_to_velo(&root),
    ] {
        if !joined.is_empty() {
            joined.push(0);
        }
        joined.extend(std::fs::read(path)?);
    }
    Ok(joined)
}
