//! Every decoder of outside input as one entry point taking raw bytes: the CDR messages the
//! node subscribes to and the whole input path they take, a `/tf` and `/tf_static` stream
//! through the tf buffer, MCAP logs (finished and cut off),
//! the fused map's checkpoint, journal and tile files, map files (PLY, SPZ, glTF binary),
//! the KITTI-360 text files, launch files, and with the `runtime` feature the worker
//! protocol, snapshot region queries, the live view's HTTP parameters, snapshot attachment
//! and topics, and ROS `camera_calibration` YAML files ([`live`]). Each entry decodes as the
//! product does and then walks what it decoded (conversions, iterations), so a malformed
//! input reaches the code a real one would.
//!
//! None may panic, hang or allocate far beyond its input, whatever the bytes: the fuzz
//! targets (`fuzz/`, coverage-guided, `scripts/fuzz.sh`) and the test suite's seeded
//! mutations of valid inputs (`node/tests/integration/decoders_mutated.rs`) both call these
//! entries, by the names in [`ENTRIES`], so the two exercise the same code.
//!
//! Decoders that read files (KITTI-360 text, MCAP, journal and tile files, YAML) get the
//! bytes written to a scratch folder of this process first ([`scratch_dir`]). An input made
//! of several binary parts (a journal segment and its tile files, a stream of input samples)
//! is cut into length-prefixed parts ([`frames`], made by [`join_frames`]); one made of
//! several text files, at NULs ([`split`]).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DAffine3, DQuat, DVec3};
use model::kitti360::poses::{read_pose_file, PoseFormat};
use model::kitti360::timestamps::read_timestamps;
use model::kitti360::{layout, Calibration};

use crate::bag::BagReader;
use crate::fusion::{
    decode_update, read_tile, segment_path, tile_path, AtTornTail, FusionConfig, GlobalMap,
    PagedTile, TileKey,
};
use crate::launch::Plan;
use crate::msg::compressed::{peek_compressed, rgb8_from_compressed, PixelLimits};
use crate::msg::encodings::{packed_rgb, Encoding};
use crate::msg::gaussians::gaussians_from_cloud;
use crate::msg::geometry_msgs::PoseStamped;
use crate::msg::image::{intrinsics_from_camera_info, rgb8_from_image, rgb_from_image};
use crate::msg::latency::{BinLatency, Diagnostics};
use crate::msg::map_update::MapUpdate;
use crate::msg::nav_msgs::{odometry_pose, Odometry, Path as NavPath};
use crate::msg::pose::affine_from_pose;
use crate::msg::sensor_msgs::{CameraInfo, CompressedImage, Image, PointCloud2};
use crate::msg::tf2_msgs::TfMessage;
use crate::msg::Message;
use crate::tf::{camera_pose_from_odometry, odometry_transform, TfBuffer, TfConfig, LATEST};

#[cfg(feature = "runtime")]
pub mod live;

/// An entry point: raw bytes in, nothing out (it must simply return).
pub type Entry = fn(&[u8]);

/// Every entry by its name (the fuzz target of the same name calls it). The entries of
/// [`live`] are there with the `runtime` feature only, as are their fuzz targets.
pub const ENTRIES: &[(&str, Entry)] = &[
    #[cfg(feature = "runtime")]
    ("camera_calibration", live::camera_calibration),
    ("cdr_camera_info", cdr_camera_info),
    ("cdr_compressed_image", cdr_compressed_image),
    ("cdr_image", cdr_image),
    ("cdr_latency", cdr_latency),
    ("cdr_map_update", cdr_map_update),
    ("cdr_odometry", cdr_odometry),
    ("cdr_path", cdr_path),
    ("cdr_point_cloud", cdr_point_cloud),
    ("cdr_pose", cdr_pose),
    ("cdr_tf", cdr_tf),
    ("glb", glb),
    ("global_map", global_map),
    ("journal_segment", journal_segment),
    ("kitti_calibration", kitti_calibration),
    ("kitti_poses", kitti_poses),
    ("kitti_timestamps", kitti_timestamps),
    ("launch", launch),
    ("mcap", mcap),
    ("mcap_recover", mcap_recover),
    #[cfg(feature = "runtime")]
    ("node_inputs", live::node_inputs),
    ("ply", ply),
    #[cfg(feature = "runtime")]
    ("region_query", live::region_query),
    ("spz", spz),
    ("tf_buffer", tf_buffer),
    ("tile_file", tile_file),
    #[cfg(feature = "runtime")]
    ("view_http_params", live::view_http_params),
    #[cfg(feature = "runtime")]
    ("view_snapshot_attachment", live::view_snapshot_attachment),
    #[cfg(feature = "runtime")]
    ("view_topics", live::view_topics),
    #[cfg(feature = "runtime")]
    ("worker_reply", live::worker_reply),
    #[cfg(feature = "runtime")]
    ("worker_request", live::worker_request),
];

/// `sensor_msgs/CameraInfo`, then the intrinsics the node takes from it.
pub fn cdr_camera_info(data: &[u8]) {
    if let Ok(msg) = CameraInfo::decode(data) {
        let _ = intrinsics_from_camera_info(&msg);
    }
}

/// `sensor_msgs/Image`, its stamp and its pixels as RGB: in the encoding it names, then
/// read as every encoding (16-bit ones in both byte orders), so each pixel path meets the
/// message's sizes and bytes.
pub fn cdr_image(data: &[u8]) {
    if let Ok(mut msg) = Image::decode(data) {
        let _ = msg.header.stamp.to_nanos();
        let _ = rgb_from_image(&msg);
        let (named, order) = (std::mem::take(&mut msg.encoding), msg.is_bigendian);
        for encoding in Encoding::ALL {
            msg.encoding = encoding.name().to_owned();
            for is_bigendian in [0, 1] {
                msg.is_bigendian = is_bigendian;
                if let Ok(encoding) = Encoding::of(&msg) {
                    let _ = packed_rgb(&msg, encoding);
                }
            }
        }
        (msg.encoding, msg.is_bigendian) = (named, order);
        let _ = rgb8_from_image(msg);
    }
}

/// `sensor_msgs/CompressedImage`, its stamp, the size its JPEG or PNG header declares,
/// and its pixels decoded under the default limits, as the node's input path would. A
/// small file may declare a large image: what is allocated for it is bounded by the limits
/// (3840x2160 RGB), not by the input.
pub fn cdr_compressed_image(data: &[u8]) {
    if let Ok(msg) = CompressedImage::decode(data) {
        let _ = msg.header.stamp.to_nanos();
        let _ = peek_compressed(&msg.data);
        let _ = rgb8_from_compressed(&msg, &PixelLimits::default());
    }
}

/// The node's latency and diagnostics messages (what `monitor` and `record` read).
pub fn cdr_latency(data: &[u8]) {
    let _ = BinLatency::decode(data);
    let _ = Diagnostics::decode(data);
}

/// A map increment or snapshot, decoded into world Gaussians as a subscriber's replica does.
pub fn cdr_map_update(data: &[u8]) {
    if let Ok(msg) = MapUpdate::decode(data) {
        let _ = decode_update(&msg);
    }
}

/// `sensor_msgs/PointCloud2` with the 3DGS fields, as Gaussians near and far from the origin.
pub fn cdr_point_cloud(data: &[u8]) {
    if let Ok(cloud) = PointCloud2::decode(data) {
        let _ = gaussians_from_cloud(&cloud, DVec3::ZERO);
        let _ = gaussians_from_cloud(&cloud, DVec3::new(1e5, -2.5e5, 30.0));
    }
}

/// `geometry_msgs/PoseStamped`, its stamp and the pose as an affine transform.
pub fn cdr_pose(data: &[u8]) {
    if let Ok(msg) = PoseStamped::decode(data) {
        let _ = msg.header.stamp.to_nanos();
        let _ = affine_from_pose(&msg);
    }
}

/// `tf2_msgs/TFMessage`, every transform's stamp and its affine form.
pub fn cdr_tf(data: &[u8]) {
    if let Ok(msg) = TfMessage::decode(data) {
        for t in &msg.transforms {
            let _ = t.header.stamp.to_nanos();
            let (p, q) = (t.transform.translation, t.transform.rotation);
            let _ = DAffine3::from_rotation_translation(
                DQuat::from_xyzw(q.x, q.y, q.z, q.w),
                DVec3::new(p.x, p.y, p.z),
            );
        }
    }
}

/// `nav_msgs/Odometry` as an odometry pose source takes it: the body's pose, the camera's
/// pose through a mount, and the pose as an edge of a tf buffer looked up at its stamp.
pub fn cdr_odometry(data: &[u8]) {
    let Ok(msg) = Odometry::decode(data) else {
        return;
    };
    let _ = odometry_pose(&msg);
    let mount = DAffine3::from_rotation_translation(
        DQuat::from_rotation_y(0.1),
        DVec3::new(0.3, -0.06, 1.2),
    );
    let _ = camera_pose_from_odometry(&msg, &mount);
    let mut tf = TfBuffer::new(TfConfig::default());
    if tf.insert(&odometry_transform(&msg), false).is_ok() {
        let stamp = msg.header.stamp.to_nanos();
        let _ = tf.lookup(&msg.header.frame_id, &msg.child_frame_id, stamp);
    }
}

/// `nav_msgs/Path` as a corrected trajectory: every pose's stamp and affine form.
pub fn cdr_path(data: &[u8]) {
    if let Ok(msg) = NavPath::decode(data) {
        for pose in &msg.poses {
            let _ = (pose.header.stamp.to_nanos(), affine_from_pose(pose));
        }
    }
}

/// Frames the [`tf_buffer`] entry's buffer holds at most (the lookups are every pair).
pub const TF_FRAMES: usize = 32;

/// A `/tf` and `/tf_static` stream as a tf listener takes it: [`frames`], each a flag byte
/// (lowest bit set: `/tf_static`) then a `TFMessage` payload; every transform inserted into
/// a buffer of [`TF_FRAMES`] frames, then every pair of frames looked up at the latest
/// common time, at the first, middle and last stamp seen and at the extremes, and through
/// static edges only.
pub fn tf_buffer(data: &[u8]) {
    let mut tf = TfBuffer::new(TfConfig {
        max_frames: TF_FRAMES,
        ..TfConfig::default()
    });
    let (mut first, mut last) = (i64::MAX, i64::MIN);
    for part in frames(data, MAX_FRAMES) {
        let Some((&flag, payload)) = part.split_first() else {
            continue;
        };
        let Ok(msg) = TfMessage::decode(payload) else {
            continue;
        };
        for t in &msg.transforms {
            let stamp = t.header.stamp.to_nanos();
            (first, last) = (first.min(stamp), last.max(stamp));
            let _ = tf.insert(t, flag & 1 == 1);
        }
    }
    let middle = first / 2 + last / 2;
    let names: Vec<&str> = tf.frames().collect();
    for target in &names {
        for source in &names {
            for stamp in [LATEST, first, middle, last, i64::MIN, i64::MAX] {
                let _ = tf.lookup(target, source, stamp);
            }
            let _ = (
                tf.latest_common(target, source),
                tf.lookup_static(target, source),
            );
        }
    }
    let _ = (tf.counts(), tf.dynamic_samples());
}

/// The fused map's checkpoint (`global_map.ssgmap`) as `run` reads it when it resumes: every
/// Gaussian walked and the snapshot taken, as the node does before it publishes the map.
pub fn global_map(data: &[u8]) {
    let Ok(map) = GlobalMap::from_bytes(data, Path::new("global_map.ssgmap")) else {
        return;
    };
    let finite = map
        .gaussians()
        .filter(|(_, g)| g.position.is_finite())
        .count();
    let _ = (finite, map.len(), map.last_bin_id(), map.snapshot());
}

/// The three KITTI-360 calibration files (`perspective.txt`, `calib_cam_to_pose.txt`,
/// `calib_cam_to_velo.txt`, joined by NULs in one input, see [`split`]), then their rig.
pub fn kitti_calibration(data: &[u8]) {
    let root = scratch_dir().join("calibration");
    let [perspective, cam_to_pose, cam_to_velo] = split::<3>(data);
    for (path, bytes) in [
        (layout::perspective(&root), perspective),
        (layout::cam_to_pose(&root), cam_to_pose),
        (layout::cam_to_velo(&root), cam_to_velo),
    ] {
        write_file(&path, bytes);
    }
    if let Ok(calibration) = Calibration::read(&root) {
        let _ = calibration.rig();
    }
}

/// A KITTI-360 pose file, read as both of its formats.
pub fn kitti_poses(data: &[u8]) {
    let path = scratch_file("poses.txt", data);
    for format in [PoseFormat::ThreeByFour, PoseFormat::FourByFour] {
        let _ = read_pose_file(&path, format);
    }
}

/// A KITTI-360 `timestamps.txt`.
pub fn kitti_timestamps(data: &[u8]) {
    let _ = read_timestamps(&scratch_file("timestamps.txt", data));
}

/// A launch file's text (UTF-8 only, as the launcher reads it).
pub fn launch(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Plan::parse(text, Path::new("fuzz.toml"), &[], Path::new("stereosplat"));
    }
}

/// An MCAP log as `replay --mcap` reads it (`BagReader::open_or_recover`: a file that is not
/// a finished recording is recovered), then every message in log-time order.
pub fn mcap(data: &[u8]) {
    let path = scratch_file("bag.mcap", data);
    if let Ok((bag, _)) = BagReader::open_or_recover(&path) {
        walk_bag(&bag);
    }
}

/// An MCAP log read as a cut-off recording (`BagReader::recover`, whatever its footer says),
/// then every message of the recovered part.
pub fn mcap_recover(data: &[u8]) {
    let path = scratch_file("cut.mcap", data);
    if let Ok((bag, recovery)) = BagReader::recover(&path) {
        let _ = recovery.to_string();
        walk_bag(&bag);
    }
}

/// A bag's summary, then its messages until the first error.
fn walk_bag(bag: &BagReader) {
    let _ = (bag.channels().len(), bag.message_count(), bag.time_range());
    for message in bag.messages() {
        if message.is_err() {
            break;
        }
    }
}

/// A journal segment as a restarting node replays it onto its base (here an empty map of the
/// default settings; a torn last record is left in the file, as `export` leaves it, where
/// the node would also cut it off: the same decoding without a sync), with the tile files
/// its records page in. The input is [`frames`]: the
/// segment, then any number of tile files, each as its version (u64) and the file's bytes,
/// written to the tiles folder under the name its own header gives
/// (`<x>_<y>_<version>.sstile`). A map replayed whole is walked as the node then uses it,
/// and saved and read back as the compactor's base.
pub fn journal_segment(data: &[u8]) {
    let parts = frames(data, MAX_FRAMES);
    let dir = fresh_dir("journal");
    let (journal, tiles) = (dir.join("journal"), dir.join("tiles"));
    let segment = segment_path(&journal, 1);
    write_file(&segment, parts.first().copied().unwrap_or_default());
    std::fs::create_dir_all(&tiles).expect("the scratch folder is writable");
    for part in parts.iter().skip(1) {
        let (version, file) = part.split_at(part.len().min(8));
        let mut v = [0u8; 8];
        v[..version.len()].copy_from_slice(version);
        let (tile, _) = tile_header(file);
        write_file(&tile_path(&tiles, tile, u64::from_le_bytes(v)), file);
    }
    let Ok(mut map) = GlobalMap::new(FusionConfig::default()) else {
        return;
    };
    let Ok(replay) = map.replay_journal(&[segment], &tiles, AtTornTail::Stop) else {
        return;
    };
    let _ = (
        replay.applied,
        map.len(),
        map.total_len(),
        map.resident_tiles(),
    );
    let near = map.paged_tiles_near(map.latest_origin().unwrap_or_default(), 1e3);
    for tile in near {
        let _ = map.read_paged_tile(&tiles, tile);
    }
    let _ = map.snapshot();
    let _ = GlobalMap::from_bytes(&map.to_bytes(), Path::new("global_map.ssgmap"));
}

/// A tile file (`<x>_<y>_<version>.sstile`) as a map pages it in: read as the tile and the
/// count its own header names (so a well-formed file is read to its end), of the default
/// settings' tiles.
pub fn tile_file(data: &[u8]) {
    let dir = fresh_dir("tiles");
    let (tile, count) = tile_header(data);
    let paged = PagedTile { version: 3, count };
    write_file(&tile_path(&dir, tile, paged.version), data);
    if let Ok(gaussians) = read_tile(&dir, tile, paged, &FusionConfig::default()) {
        let _ = gaussians
            .iter()
            .filter(|(_, g)| g.is_finite() && g.position.z > 0.0)
            .count();
    }
}

/// The tile and Gaussian count a tile file's header names (magic 8 bytes, version 4, then x,
/// y and count, 8 bytes each); zeros where the file is too short.
fn tile_header(file: &[u8]) -> (TileKey, u64) {
    let field = |at: usize| {
        let mut b = [0u8; 8];
        if let Some(bytes) = file.get(at..at + 8) {
            b.copy_from_slice(bytes);
        }
        u64::from_le_bytes(b)
    };
    ((field(12) as i64, field(20) as i64), field(28))
}

/// A 3DGS PLY file (binary or ASCII).
pub fn ply(data: &[u8]) {
    let _ = renderer::ply::read_ply(data);
}

/// An SPZ file (gzip), as `render --map` and `export --map` read it.
pub fn spz(data: &[u8]) {
    let _ = renderer::formats::spz::read_spz(data);
}

/// A binary glTF file with `KHR_gaussian_splatting`, as `render --map` and `export --map`
/// read it.
pub fn glb(data: &[u8]) {
    let _ = renderer::formats::glb::read_glb(data);
}

/// This thread's scratch folder (under the system temporary folder, one per process and
/// thread, so parallel runs do not overwrite each other's files), made on first use.
pub fn scratch_dir() -> PathBuf {
    static THREADS: AtomicUsize = AtomicUsize::new(0);
    thread_local! {
        static DIR: PathBuf = {
            let n = THREADS.fetch_add(1, Ordering::Relaxed);
            let dir = std::env::temp_dir()
                .join(format!("stereosplat-input-{}-{n}", std::process::id()));
            std::fs::create_dir_all(&dir).expect("the temporary folder is writable");
            dir
        };
    }
    DIR.with(PathBuf::clone)
}

/// The folder `name` in [`scratch_dir`], emptied: what an earlier input left there is gone.
pub fn fresh_dir(name: &str) -> PathBuf {
    let dir = scratch_dir().join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("the scratch folder is writable");
    dir
}

/// Writes `bytes` to `name` in [`scratch_dir`] and returns its path, for decoders that take
/// a path.
pub fn scratch_file(name: &str, bytes: &[u8]) -> PathBuf {
    let path = scratch_dir().join(name);
    write_file(&path, bytes);
    path
}

/// Writes `bytes` to `path`, creating its parent folders (a path under [`scratch_dir`]). An
/// earlier file there is removed first rather than truncated: on ext4 a write over a
/// truncated file waits for its blocks (`auto_da_alloc`), 15 times slower here.
fn write_file(path: &Path, bytes: &[u8]) {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).expect("the scratch folder is writable");
    }
    let _ = std::fs::remove_file(path);
    std::fs::write(path, bytes).expect("the scratch folder is writable");
}

/// `data` cut at its first `N - 1` NUL bytes into `N` parts (the last ones empty when there
/// are fewer NULs): one input becomes several text files, and the seeds join files with a
/// NUL, which no text file of the formats holds.
pub fn split<const N: usize>(data: &[u8]) -> [&[u8]; N] {
    let mut parts = [&data[data.len()..]; N];
    let mut rest = data;
    for part in parts.iter_mut().take(N - 1) {
        match rest.iter().position(|&b| b == 0) {
            Some(at) => {
                *part = &rest[..at];
                rest = &rest[at + 1..];
            }
            None => {
                *part = rest;
                rest = &rest[rest.len()..];
            }
        }
    }
    parts[N - 1] = rest;
    parts
}

/// Parts one input is cut into at most ([`frames`]).
pub const MAX_FRAMES: usize = 64;

/// `data` as length-prefixed parts: a little-endian u32 length, then that many bytes, over
/// and over; a length past the end takes what is left, and a last length cut short is a
/// part of its own bytes. At most `max` parts (the last takes the rest).
pub fn frames(data: &[u8], max: usize) -> Vec<&[u8]> {
    let mut parts = Vec::new();
    let mut rest = data;
    while !rest.is_empty() && parts.len() < max {
        if parts.len() + 1 == max || rest.len() < 4 {
            parts.push(rest);
            break;
        }
        let len = u32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]) as usize;
        let body = &rest[4..];
        let len = len.min(body.len());
        parts.push(&body[..len]);
        rest = &body[len..];
    }
    parts
}

/// `parts` joined as [`frames`] cuts them (for seeds and tests).
pub fn join_frames(parts: &[&[u8]]) -> Vec<u8> {
    let mut out = Vec::new();
    for part in parts {
        out.extend_from_slice(&(part.len() as u32).to_le_bytes());
        out.extend_from_slice(part);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_cuts_at_the_first_nuls_and_pads_with_empty_parts() {
        assert_eq!(split::<3>(b"a\0b\0c\0d"), [&b"a"[..], b"b", b"c\0d"]);
        assert_eq!(split::<3>(b"a"), [&b"a"[..], b"", b""]);
        assert_eq!(split::<2>(b""), [&b""[..], b""]);
    }

    #[test]
    fn frames_cut_at_their_lengths_and_keep_what_is_left() {
        let joined = join_frames(&[b"ab", b"", b"xyz"]);
        assert_eq!(frames(&joined, 8), [&b"ab"[..], b"", b"xyz"]);
        assert_eq!(frames(&joined, 2), [&b"ab"[..], &joined[6..]]);
        // A length past the end takes the rest; a cut length is a part of its bytes.
        assert_eq!(frames(b"\xff\0\0\0abc", 8), [&b"abc"[..]]);
        assert_eq!(frames(b"\x01\0\0\0ab\0", 8), [&b"a"[..], b"b\0"]);
        assert!(frames(b"", 8).is_empty());
    }

    #[test]
    fn every_entry_returns_on_empty_and_junk_input() {
        for &(name, entry) in ENTRIES {
            for input in [&b""[..], b"\0", b"\xff\xff\xff\xff", b"ply\nformat"] {
                entry(input);
            }
            assert!(!name.is_empty());
        }
    }
}
