//! The node bounded by its input limits, whatever the input's size: each probe below goes to a
//! node running in this process on loopback, then a small generated drive follows. Checked for
//! each: the probe is counted under its reason, the process's resident memory after probe and
//! drive stays under [`RSS_BOUND`], and every bin the drive opens is published with a
//! non-empty map.
//!
//! Probes: one 2000x2000 frame (worked at the working size, not refused), 16 left images of
//! 8000x8000 `rgb8` (192 MB each), an 8000x8000 header with no pixels, a `0 x 4e9` image, a
//! pose 1e30 m from the origin, camera infos with fx = 1e39, a snapshot query on a
//! wildcard, and 20 snapshot queries in a row. The tests run one at a time (the binary's
//! lock) so each one's memory is its own.

use std::time::{Duration, Instant};

use crate::drive_support::{rss_bytes, Collector, Drive, Player, RunningNode};
use glam::{DAffine3, DVec3};
use model::kitti360::resample::resample_area;
use model::synth::SynthConfig;
use node::msg::image::{camera_info, image_from_rgb};
use node::msg::map_update::MapUpdate;
use node::msg::pose::pose_from_affine;
use node::msg::sensor_msgs::{Image, PointCloud2};
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::pipeline::worker::RenderWith;
use node::service::{InputLimits, NodeConfig, NodeSummary};
use node::transport::Keys;

/// Resident memory of this test process (node, model, zenoh and test) after any probe and
/// its drive. A 2000x2000 frame worked at full size rather than the working size would take
/// the worker to about 5.7 GB.
const RSS_BOUND: u64 = 1536 << 20;

/// A node, a drive for it, a player and a collector of its bin maps.
struct Bench {
    drive: Drive,
    keys: Keys,
    node: RunningNode,
    player: Player,
    maps: Collector,
}

impl Bench {
    /// A node with `limits` (renders off, exports under the drive's `out/`) and a drive of
    /// 40 frames at 136x40.
    async fn start(tag: &str, limits: InputLimits) -> Self {
        let drive = Drive::generate(
            tag,
            &SynthConfig {
                seed: 23,
                frames: 40,
                width: 136,
                height: 40,
                lidar_azimuth_steps: 64,
                ..SynthConfig::default()
            },
        );
        let keys = Keys::new(tag);
        let node = RunningNode::start(NodeConfig {
            keys: keys.clone(),
            queue_capacity: 64,
            renders: RenderWith::Off,
            out_dir: Some(drive.dir("out")),
            limits,
            ..NodeConfig::default()
        })
        .await;
        let maps = Collector::connect(&node, &[keys.bin_map()]).await;
        let player = Player::connect(&node).await;
        Self {
            drive,
            keys,
            node,
            player,
            maps,
        }
    }

    /// A frame of the drive's first view at `size` (camera infos scaled to it), stamped
    /// `stamp_ns`, with pose `pose`.
    async fn frame_at(&self, size: (u32, u32), stamp_ns: i64, pose: &DAffine3) {
        let (_, f) = &self.drive.frames[0];
        let k = self.drive.rig.intrinsics.scaled(size.0, size.1);
        let header = |id: &str| Header::new(stamp_ns, id);
        let k_ = &self.keys;
        let p = &self.player;
        p.put(
            k_.left_info(),
            camera_info(&k, 0.0, header("left")).encode(),
        )
        .await;
        let right = camera_info(&k, self.drive.rig.baseline, header("right"));
        p.put(k_.right_info(), right.encode()).await;
        for (key, img, id) in [
            (k_.left_image(), &f.left, "left"),
            (k_.right_image(), &f.right, "right"),
        ] {
            let big = resample_area(img, size.0, size.1);
            p.put(key, image_from_rgb(&big, header(id)).encode()).await;
        }
        p.put(k_.pose(), pose_from_affine(pose, header("world")).encode())
            .await;
    }

    /// Plays the drive and waits for `probe_bins` more bin maps than the drive opens.
    async fn play(&self, probe_bins: usize) {
        self.player.drive(&self.drive, DAffine3::IDENTITY, 0).await;
        let expected = self.drive.bins_opened(8.0) + probe_bins;
        assert!(
            self.maps.wait_count(&self.keys.bin_map(), expected).await,
            "{expected} bin maps"
        );
        assert!(self.node.is_running());
    }

    /// [`Bench::play`], then [`Bench::stop`].
    async fn drive_and_stop(self, probe_bins: usize) -> (NodeSummary, Drive) {
        self.play(probe_bins).await;
        self.stop(probe_bins).await
    }

    /// Stops the node and checks: RSS under the bound, every bin map published and
    /// non-empty.
    async fn stop(self, probe_bins: usize) -> (NodeSummary, Drive) {
        let expected = self.drive.bins_opened(8.0) + probe_bins;
        let summary = self.node.stop().await;
        let rss = rss_bytes();
        eprintln!("RSS after probe and drive: {} MiB", rss >> 20);
        assert!(rss < RSS_BOUND, "RSS {} MiB", rss >> 20);
        assert_eq!(summary.bins_published, expected as u64, "{summary:?}");
        let maps: Vec<PointCloud2> = self.maps.decoded(&self.keys.bin_map());
        assert_eq!(maps.len(), expected);
        for m in &maps {
            assert!(m.width * m.height > 0, "bin {} is empty", m.header.frame_id);
        }
        (summary, self.drive)
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_2000x2000_frame_is_reconstructed_at_the_working_size() {
    let _serial = crate::SERIAL.lock().await;
    let bench = Bench::start("limbig", InputLimits::default()).await;
    // 2 s before the drive, 10 m behind its first pose along the view: a bin of its own.
    let (t0, f0) = &bench.drive.frames[0];
    let behind = f0.left_to_world * DAffine3::from_translation(DVec3::new(0.0, 0.0, -10.0));
    bench
        .frame_at((2000, 2000), t0 - 2_000_000_000, &behind)
        .await;
    let start = Instant::now();
    assert!(
        bench.maps.wait_count(&bench.keys.bin_map(), 1).await,
        "the 2000x2000 bin comes out"
    );
    eprintln!(
        "2000x2000 frame to bin map: {:.1} s, RSS {} MiB",
        start.elapsed().as_secs_f64(),
        rss_bytes() >> 20
    );
    let first: Vec<PointCloud2> = bench.maps.decoded(&bench.keys.bin_map());
    assert!(first[0].width * first[0].height > 0);
    let (summary, _) = bench.drive_and_stop(1).await;
    assert_eq!(
        summary.counters.get("input/downscaled"),
        2,
        "left and right"
    );
    assert_eq!(
        summary.counters.sum("refused/"),
        0,
        "{:?}",
        summary.counters
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn oversized_and_empty_images_are_refused_before_decoding() {
    let _serial = crate::SERIAL.lock().await;
    let bench = Bench::start("limhuge", InputLimits::default()).await;
    let header = Header::new(bench.drive.frames[0].0 - 1_000_000_000, "left");
    let huge = |w: u32, h: u32, data: Vec<u8>| Image {
        header: header.clone(),
        width: w,
        height: h,
        encoding: "rgb8".into(),
        is_bigendian: 0,
        step: 3 * w,
        data,
    };
    // 16 real 8000x8000 left images (192 MB each): over the message limit.
    let payload = huge(8000, 8000, vec![128; 3 * 8000 * 8000]).encode();
    for _ in 0..16 {
        bench
            .player
            .put(bench.keys.left_image(), payload.clone())
            .await;
    }
    drop(payload);
    // The same size declared with no pixel data, and a 0 x 4e9 image.
    let lying = huge(8000, 8000, Vec::new()).encode();
    bench.player.put(bench.keys.left_image(), lying).await;
    let mut empty = huge(0, 4_000_000_000, Vec::new());
    empty.step = 0;
    bench
        .player
        .put(bench.keys.right_image(), empty.encode())
        .await;
    let (summary, _) = bench.drive_and_stop(0).await;
    let c = &summary.counters;
    assert_eq!(c.get("refused/message_too_large"), 16, "{c:?}");
    assert_eq!(c.get("refused/image_too_large"), 1, "{c:?}");
    assert_eq!(c.get("refused/image_empty"), 1, "{c:?}");
    assert_eq!(c.get("bad_message/left_image"), 17);
    assert_eq!(c.get("bad_message/right_image"), 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pose_1e30_m_away_is_refused_and_the_map_keeps_its_shape() {
    let _serial = crate::SERIAL.lock().await;
    let bench = Bench::start("limpose", InputLimits::default()).await;
    let (t0, f0) = &bench.drive.frames[0];
    let far = DAffine3::from_mat3_translation(f0.left_to_world.matrix3, DVec3::splat(1e30));
    bench.frame_at((136, 40), t0 - 1_000_000_000, &far).await;
    let (summary, drive) = bench.drive_and_stop(0).await;
    assert_eq!(summary.counters.get("refused/pose_out_of_range"), 1);
    assert_eq!(summary.counters.get("bad_message/pose"), 1);
    let set = renderer::ply::load_ply(drive.dir("out").join("global_map.ply")).unwrap();
    let mut xs: Vec<u32> = set.means.iter().map(|m| m.x.to_bits()).collect();
    xs.sort_unstable();
    xs.dedup();
    assert!(
        xs.len() > 1000,
        "{} distinct x in the exported map",
        xs.len()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn camera_infos_with_fx_1e39_are_refused() {
    let _serial = crate::SERIAL.lock().await;
    let bench = Bench::start("limfx", InputLimits::default()).await;
    let rig = bench.drive.rig;
    let stamp = bench.drive.frames[0].0 - 1_000_000_000;
    let mut left = camera_info(&rig.intrinsics, 0.0, Header::new(stamp, "left"));
    let mut right = camera_info(&rig.intrinsics, rig.baseline, Header::new(stamp, "right"));
    for info in [&mut left, &mut right] {
        info.p[0] = 1e39;
        info.k[0] = 1e39;
    }
    right.p[3] = -1e39 * rig.baseline;
    bench
        .player
        .put(bench.keys.left_info(), left.encode())
        .await;
    bench
        .player
        .put(bench.keys.right_info(), right.encode())
        .await;
    let (summary, _) = bench.drive_and_stop(0).await;
    assert_eq!(summary.counters.get("refused/camera_info"), 2);
}

/// Every reply to a query on `key`: the payload of each, `Ok` for a sample, `Err` for an
/// error reply.
async fn query(session: &zenoh::Session, key: &str) -> Vec<Result<Vec<u8>, String>> {
    let replies = session.get(key).await.unwrap();
    let mut all = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        all.push(match reply.result() {
            Ok(s) => Ok(s.payload().to_bytes().to_vec()),
            Err(e) => Err(String::from_utf8_lossy(&e.payload().to_bytes()).into_owned()),
        });
    }
    all
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wildcard_snapshot_query_gets_an_error_not_the_map() {
    let _serial = crate::SERIAL.lock().await;
    let bench = Bench::start("limwild", InputLimits::default()).await;
    bench.play(0).await;
    let session = &bench.player.session;
    let wild = query(session, "limwild/**").await;
    assert_eq!(wild.len(), 1, "one reply");
    let err = wild[0].clone().unwrap_err();
    assert!(err.contains("limwild/map/snapshot"), "{err}");
    let exact = query(session, &bench.keys.snapshot_request()).await;
    let snapshot = MapUpdate::decode(exact[0].as_ref().unwrap()).unwrap();
    assert!(snapshot.snapshot);
    let (summary, _) = bench.stop(0).await;
    assert_eq!(summary.counters.get("refused/snapshot_key"), 1);
    assert_eq!(summary.counters.get("refused/snapshot_rate"), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rapid_snapshot_queries_get_one_answer_per_interval() {
    let _serial = crate::SERIAL.lock().await;
    let limits = InputLimits {
        // Long enough that the 20 queries below all fall in one interval on any machine.
        snapshot_interval: Duration::from_secs(600),
        ..InputLimits::default()
    };
    let bench = Bench::start("limrate", limits).await;
    let key = bench.keys.snapshot_request();
    let mut answered = 0;
    let mut refused = 0;
    for _ in 0..20 {
        for reply in query(&bench.player.session, &key).await {
            match reply {
                Ok(_) => answered += 1,
                Err(e) => {
                    assert!(e.contains("at most one snapshot"), "{e}");
                    refused += 1;
                }
            }
        }
    }
    assert_eq!((answered, refused), (1, 19));
    let (summary, _) = bench.drive_and_stop(0).await;
    assert_eq!(summary.counters.get("refused/snapshot_rate"), 19);
}
