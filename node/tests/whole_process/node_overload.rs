//! Overload: generated frames at 20 times the recorded frame rate for 20 s into a node running
//! as its own process (`stereosplat run --method sgm`, so its memory is its own), then a drive
//! at the recorded rate.
//!
//! The frames are a generated drive (272 x 72) looped with stamps going on at 10 Hz, put
//! every 5 ms of wall clock with zenoh's `Drop` congestion control (the test never waits for
//! the node). Checked, with numbers: the node's resident memory (VmRSS sampled every 0.5 s,
//! and VmHWM at the end) stays under a stated bound; its drops are counted (the worker queue's
//! on `diagnostics`, and frames lost before the binner in the synchroniser's counters or not
//! taken by zenoh); afterwards the drive replayed at 1x gives every one of its bins (the jump
//! back in time resets the synchroniser), each with arrival-to-publish under a generous guard.
//! The node restarts itself under the allocator's settings (`node::memory`) unless
//! the test was given `GLIBC_TUNABLES`. The figures are printed.

use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::drive_support::{bin_of_frame_id, net_support, wait_for, Drive, Received};
use glam::DAffine3;
use model::bins::{make_bins, BinConfig, BinLayout};
use node::bag::Rate;
use node::clients::replay;
use node::msg::geometry_msgs::PoseStamped;
use node::msg::image::image_from_rgb;
use node::msg::latency::{BinLatency, Diagnostics};
use node::msg::pose::{affine_from_pose, pose_from_affine};
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::transport::Keys;
use node::transport::{open, TransportConfig};
use zenoh::qos::CongestionControl;
use zenoh::Session;

/// Seconds of overload.
const OVERLOAD_S: u64 = 20;
/// Wall-clock time between frames put: 20 x the recorded 10 Hz.
const PERIOD: Duration = Duration::from_millis(5);
/// Bin length, metres: at 20x over 100 bins open per second, more than SGM takes at this
/// size (seen: about 30 per second when it has the cores to itself); at 1x about 6.
const BIN_M: f64 = 1.0;
const MIB: f64 = 1024.0 * 1024.0;
/// The node's resident memory may not exceed this. What it can hold is bounded whatever the
/// input rate: 16 messages and 64 MiB per stream in the synchroniser (16 decoded frames of
/// 272 x 72 are 2 x 16 x 235 KB here), 2 bins queued, one map in flight, the global map
/// under its Gaussian budget (default 2 million, far from reached by a few hundred
/// small bins), zenoh's bounded queues, and the allocator's arenas. Seen: 93 to 141 MiB
/// (VmHWM) on the 2-core development machine.
const RSS_BOUND_MIB: f64 = 300.0;

/// `stereosplat run` on a free loopback port; killed when dropped.
struct NodeProcess {
    child: Child,
    endpoint: String,
}

impl NodeProcess {
    fn start(namespace: &str, out: &std::path::Path) -> Self {
        let endpoint = format!("tcp/127.0.0.1:{}", net_support::free_port());
        let child = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
            .args(["run", "--listen", &endpoint, "--namespace", namespace])
            .args(["--method", "sgm", "--renders", "off", "--queue", "2"])
            .args(["--bin-length", &BIN_M.to_string(), "--snapshot-every", "0"])
            .arg("--out")
            .arg(out)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("stereosplat run starts");
        Self { child, endpoint }
    }

    /// (VmRSS, VmHWM) in bytes.
    fn memory(&self) -> (u64, u64) {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id()))
            .expect("/proc/PID/status");
        let kib = |field: &str| {
            status
                .lines()
                .find_map(|l| l.strip_prefix(field))
                .and_then(|v| v.split_whitespace().next())
                .and_then(|v| v.parse::<u64>().ok())
                .unwrap_or_else(|| panic!("{field} in /proc/PID/status"))
                * 1024
        };
        (kib("VmRSS:"), kib("VmHWM:"))
    }

    /// Whether the process restarted itself under the allocator's settings
    /// (`node::memory::ALLOCATOR_TUNABLES`): its starting environment (what
    /// `/proc/PID/environ` shows) holds the restart's marker.
    fn restarted_with_allocator_settings(&self) -> bool {
        let environ =
            std::fs::read(format!("/proc/{}/environ", self.child.id())).expect("/proc/PID/environ");
        environ
            .split(|&b| b == 0)
            .any(|v| v == b"STEREOSPLAT_ALLOCATOR_RESTARTED=1")
    }

    /// SIGTERM, then the JSON summary it prints on stdout.
    fn stop(mut self) -> serde_json::Value {
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).unwrap();
        let mut stdout = String::new();
        use std::io::Read;
        self.child
            .stdout
            .take()
            .unwrap()
            .read_to_string(&mut stdout)
            .unwrap();
        let status = self.child.wait().unwrap();
        assert!(status.success(), "stereosplat run: {status}");
        let line = stdout.lines().last().expect("a summary line");
        serde_json::from_str(line).unwrap_or_else(|e| panic!("{line}: {e}"))
    }
}

impl Drop for NodeProcess {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Every sample on the node's bin pose, latency, diagnostics and bin map keys, in arrival
/// order (of a map only its first 256 bytes, its header: its `frame_id` names the bin).
async fn listen(
    session: &Session,
    keys: &Keys,
) -> (
    Arc<Mutex<Vec<Received>>>,
    Vec<zenoh::pubsub::Subscriber<()>>,
) {
    let samples: Arc<Mutex<Vec<Received>>> = Arc::default();
    let mut subscribers = Vec::new();
    let wanted = [
        keys.bin_pose(),
        keys.latency(),
        keys.diagnostics(),
        keys.bin_map(),
    ];
    let map_key = keys.bin_map();
    for key in wanted {
        let sink = samples.clone();
        let keep = if key == map_key { 256 } else { usize::MAX };
        let sub = session
            .declare_subscriber(key)
            .callback(move |s| {
                let bytes = s.payload().to_bytes();
                let item = (
                    s.key_expr().as_str().to_string(),
                    bytes[..bytes.len().min(keep)].to_vec(),
                );
                sink.lock().unwrap().push(item);
            })
            .await
            .unwrap();
        subscribers.push(sub);
    }
    (samples, subscribers)
}

fn decoded<T: Message>(samples: &Mutex<Vec<Received>>, key: &str, from: usize) -> Vec<T> {
    let all = samples.lock().unwrap();
    all[from.min(all.len())..]
        .iter()
        .filter(|(k, _)| k == key)
        .map(|(_, p)| T::decode(p).unwrap())
        .collect()
}

fn counter(d: &Diagnostics, kind: &str) -> u64 {
    d.counters
        .iter()
        .find(|c| c.kind == kind)
        .map_or(0, |c| c.count)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twenty_times_the_frame_rate_keeps_memory_bounded_and_the_node_recovers() {
    let _serial = crate::SERIAL.lock().await;
    let drive = Drive::small("overload");
    let keys = Keys::new("overload");
    let node = NodeProcess::start(&keys.namespace, &drive.dir("out"));
    let client = TransportConfig {
        connect: vec![node.endpoint.clone()],
        ..TransportConfig::default()
    };
    // The node takes a moment to listen: retry the connection until it answers.
    let session = {
        let mut tries = 0;
        loop {
            match open(&client).await {
                Ok(s) => break s,
                Err(e) if tries < 60 => {
                    tries += 1;
                    let _ = e;
                    tokio::time::sleep(Duration::from_millis(500)).await;
                }
                Err(e) => panic!("the node never listened: {e}"),
            }
        }
    };
    let (samples, _subs) = listen(&session, &keys).await;
    tokio::time::sleep(Duration::from_secs(1)).await;
    let (rss_start, _) = node.memory();
    // A node started without GLIBC_TUNABLES runs with the allocator's settings; one given
    // the variable keeps it.
    assert_eq!(
        node.restarted_with_allocator_settings(),
        std::env::var_os("GLIBC_TUNABLES").is_none()
    );

    // The overload: frame k of the loop stamped k x 100 ms, put every 5 ms.
    let infos = |t: i64| {
        [
            (
                keys.left_info(),
                node::msg::image::camera_info(&drive.rig.intrinsics, 0.0, Header::new(t, "left"))
                    .encode(),
            ),
            (
                keys.right_info(),
                node::msg::image::camera_info(
                    &drive.rig.intrinsics,
                    drive.rig.baseline,
                    Header::new(t, "right"),
                )
                .encode(),
            ),
        ]
    };
    let put = |key: String, payload: Vec<u8>| {
        let session = &session;
        async move {
            session
                .put(key, payload)
                .congestion_control(CongestionControl::Drop)
                .await
                .unwrap()
        }
    };
    let mut ticker = tokio::time::interval(PERIOD);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let start = Instant::now();
    let (mut sent, mut rss_max) = (0usize, rss_start);
    let mut last_sample = Instant::now();
    while start.elapsed() < Duration::from_secs(OVERLOAD_S) {
        ticker.tick().await;
        let (_, f) = &drive.frames[sent % drive.frames.len()];
        let t = sent as i64 * 100_000_000;
        if sent % 10 == 0 {
            for (k, p) in infos(t) {
                put(k, p).await;
            }
        }
        let h = |id: &str| Header::new(t, id);
        put(
            keys.left_image(),
            image_from_rgb(&f.left, h("left")).encode(),
        )
        .await;
        put(
            keys.right_image(),
            image_from_rgb(&f.right, h("right")).encode(),
        )
        .await;
        put(
            keys.pose(),
            pose_from_affine(&f.left_to_world, h("world")).encode(),
        )
        .await;
        sent += 1;
        if last_sample.elapsed() > Duration::from_millis(500) {
            rss_max = rss_max.max(node.memory().0);
            last_sample = Instant::now();
        }
    }
    let overload_s = start.elapsed().as_secs_f64();
    let rate = sent as f64 / overload_s;
    let (_, hwm_overload) = node.memory();

    // Let the node drain: the worker queue holds 2 bins at most.
    let bins_during = decoded::<PoseStamped>(&samples, &keys.bin_pose(), 0).len();
    let mut last = usize::MAX;
    while decoded::<PoseStamped>(&samples, &keys.bin_pose(), 0).len() != last {
        last = decoded::<PoseStamped>(&samples, &keys.bin_pose(), 0).len();
        tokio::time::sleep(Duration::from_secs(2)).await;
    }
    let maps_during: Vec<u64> = decoded::<Header>(&samples, &keys.bin_map(), 0)
        .iter()
        .map(|h| bin_of_frame_id(&h.frame_id))
        .collect();
    let diag = decoded::<Diagnostics>(&samples, &keys.diagnostics(), 0);
    let after_overload = diag
        .last()
        .expect("diagnostics during the overload")
        .clone();

    // The drive at the recorded rate, stamps from 0 again.
    let mark = samples.lock().unwrap().len();
    let replayed = replay(
        &session,
        &keys,
        &drive.sequence,
        Rate::Recorded,
        &mut |_, _| {},
    )
    .await
    .unwrap();
    assert_eq!(replayed.frames as usize, drive.frames.len());
    let poses = drive.poses();
    let bins = make_bins(
        &poses,
        &BinConfig {
            length_m: BIN_M,
            layout: BinLayout::Consecutive,
        },
    );
    let mut firsts: Vec<DAffine3> = bins.iter().map(|b| poses[b.first]).collect();
    firsts.push(poses[bins.last().unwrap().last]);
    let got_all = wait_for(Duration::from_secs(60), || {
        decoded::<PoseStamped>(&samples, &keys.bin_pose(), mark).len() >= firsts.len()
    })
    .await;
    tokio::time::sleep(Duration::from_secs(2)).await;
    let (rss_end, hwm) = node.memory();
    let summary = node.stop();

    let counters = &summary["counters"];
    let count = |k: &str| counters[k].as_u64().unwrap_or(0);
    let after: Vec<DAffine3> = decoded::<PoseStamped>(&samples, &keys.bin_pose(), mark)
        .iter()
        .map(|p| affine_from_pose(p).unwrap())
        .collect();
    let latencies: Vec<BinLatency> = decoded(&samples, &keys.latency(), mark);
    let worst_s = latencies
        .iter()
        .map(|l| (l.publish_ns - l.first_frame_arrival_ns) as f64 / 1e9)
        .fold(0.0, f64::max);
    println!(
        "overload: {sent} frames in {overload_s:.1} s ({rate:.0} per s, {:.1}x the recorded \
         10 Hz), {bins_during} bins published during it (ids up to {:?}); node RSS {:.1} MiB at start, max \
         sampled {:.1} MiB, VmHWM {:.1} MiB after the overload, {:.1} MiB at the end (VmHWM \
         {:.1}); counters after the overload: worker queue drops {}, sync late {} unmatched {} \
         over budget {} conflict {} outlier {} reset {}, bad messages {}; at the end {}; 1x \
         drive: {} of {} bins, worst arrival-to-publish {worst_s:.2} s over {} latencies",
        rate / 10.0,
        maps_during.iter().max(),
        rss_start as f64 / MIB,
        rss_max as f64 / MIB,
        hwm_overload as f64 / MIB,
        rss_end as f64 / MIB,
        hwm as f64 / MIB,
        counter(&after_overload, "dropped/worker_queue"),
        counter(&after_overload, "sync/late"),
        counter(&after_overload, "sync/unmatched"),
        counter(&after_overload, "sync/over_budget"),
        counter(&after_overload, "sync/conflict"),
        counter(&after_overload, "sync/outlier"),
        counter(&after_overload, "sync/reset"),
        after_overload
            .counters
            .iter()
            .filter(|c| c.kind.starts_with("bad_message/"))
            .map(|c| c.count)
            .sum::<u64>(),
        counters,
        after.len(),
        firsts.len(),
        latencies.len(),
    );

    // Memory bounded by the stated figure, whatever the rate.
    assert!(
        (hwm as f64) < RSS_BOUND_MIB * MIB,
        "VmHWM {:.1} MiB over the bound {RSS_BOUND_MIB} MiB",
        hwm as f64 / MIB
    );
    // The overload did overload, and the node counted what it dropped: bins opened beyond
    // what the worker took are worker-queue drops.
    assert!(rate > 100.0, "only {rate:.0} frames per s were put");
    let worker_drops = counter(&after_overload, "dropped/worker_queue");
    assert!(worker_drops > 0, "{after_overload:?}");
    let opened = maps_during.iter().max().unwrap() + 1;
    assert_eq!(
        maps_during.len() as u64 + worker_drops,
        opened,
        "every bin opened in the overload was published or counted as dropped"
    );
    assert_eq!(
        count("dropped/worker_queue"),
        worker_drops,
        "no drop after the overload"
    );
    // Recovered: every bin of the 1x drive, in order, with a latency under a generous guard.
    assert!(
        got_all,
        "{} of {} bins after the overload",
        after.len(),
        firsts.len()
    );
    assert_eq!(after.len(), firsts.len());
    for (i, (g, w)) in after.iter().zip(&firsts).enumerate() {
        assert!(
            g.translation.distance(w.translation) < 1e-6,
            "bin {i} of the 1x drive"
        );
    }
    assert!(
        count("sync/reset") >= 1,
        "the jump back to stamp 0 was confirmed"
    );
    assert!(latencies.len() >= firsts.len() - 1);
    assert!(
        worst_s < 10.0,
        "arrival to publish {worst_s:.2} s after the overload"
    );
}
