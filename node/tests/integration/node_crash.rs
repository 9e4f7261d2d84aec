//! A crash loses nothing that was published. The `stereosplat` binary runs as a child
//! process on loopback (SGM, a generated drive): it is killed with SIGKILL after some bins
//! were published, restarted on the same `--out`, and the drive finished. The restart
//! resumes the checkpoint: the resumed map's first update is a snapshot equal to what
//! subscribers had before the kill, at the same sequence number; bin ids, Gaussian ids and
//! sequence numbers go on without reuse; the final map holds every Gaussian published
//! before the kill that no later bin replaced. A checkpoint that does not load stops the
//! node and is kept; `--fresh` moves it aside. A recorder killed with SIGKILL leaves an MCAP
//! file that `replay --mcap` reads as far as its complete chunks go, saying so.

use crate::drive_support;

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use drive_support::{bin_of_frame_id, wait_for, Collector, Drive, Player};
use model::bins::{make_bins, BinConfig, BinLayout};
use model::synth::SynthConfig;
use node::bag::BagReader;
use node::fusion::AtTornTail;
use node::fusion::{decode_update, GaussianId, GlobalMap, MapReplica, Snapshot, Update};
use node::msg::latency::Diagnostics;
use node::msg::map_update::MapUpdate;
use node::msg::pose::pose_from_affine;
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::store::map_files::restore;
use node::transport::open;
use node::transport::Keys;
use zenoh::qos::CongestionControl;

/// A `stereosplat` process with its stderr collected as it is written.
pub(crate) struct Child {
    process: std::process::Child,
    stderr: Arc<Mutex<String>>,
}

impl Child {
    /// Starts `stereosplat args`.
    pub(crate) fn spawn(args: &[&str]) -> Self {
        let mut process = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("stereosplat starts");
        let stderr: Arc<Mutex<String>> = Arc::default();
        let (sink, pipe) = (stderr.clone(), process.stderr.take().unwrap());
        std::thread::spawn(move || {
            for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                let mut s = sink.lock().unwrap();
                s.push_str(&line);
                s.push('\n');
            }
        });
        Self { process, stderr }
    }

    /// Everything written to stderr so far.
    pub(crate) fn stderr(&self) -> String {
        self.stderr.lock().unwrap().clone()
    }

    /// Kills it with SIGKILL (no chance to save anything) and reaps it.
    pub(crate) fn kill_9(mut self) {
        self.process.kill().unwrap();
        self.process.wait().unwrap();
    }

    /// Sends SIGTERM (a clean stop), waits; its exit status, stdout and stderr.
    pub(crate) fn terminate(self) -> (ExitStatus, String, String) {
        let pid = nix::unistd::Pid::from_raw(self.process.id() as i32);
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).unwrap();
        self.wait()
    }

    /// Waits for it to exit; its exit status, stdout and stderr.
    fn wait(mut self) -> (ExitStatus, String, String) {
        let status = self.process.wait().unwrap();
        let mut out = String::new();
        let mut stdout = self.process.stdout.take().unwrap();
        stdout.read_to_string(&mut out).unwrap();
        std::thread::sleep(Duration::from_millis(200));
        (status, out, self.stderr())
    }
}

/// Starts `stereosplat run` (SGM, no renders, a snapshot only on request) on a free loopback
/// port with `--out out`, plus `extra` flags; returns it and its endpoint once it listens.
pub(crate) async fn start_node(ns: &str, out: &Path, extra: &[&str]) -> (Child, String) {
    let port = drive_support::free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let out = out.to_str().unwrap();
    let mut args = vec![
        "run",
        "--listen",
        &endpoint,
        "--namespace",
        ns,
        "--method",
        "sgm",
        "--renders",
        "off",
        "--queue",
        "64",
        "--snapshot-every",
        "0",
        "--out",
        out,
    ];
    args.extend_from_slice(extra);
    let child = Child::spawn(&args);
    let listening = wait_for(Duration::from_secs(60), || {
        std::net::TcpStream::connect(("127.0.0.1", port)).is_ok()
    })
    .await;
    assert!(listening, "the node listens: {}", child.stderr());
    (child, endpoint)
}

/// Bins the node opens on frames with these poses (closed bins plus the open one).
fn bins_opened(poses: &[glam::DAffine3]) -> usize {
    let config = BinConfig {
        length_m: 8.0,
        layout: BinLayout::Consecutive,
    };
    make_bins(poses, &config).len() + 1
}

/// Plays frames `range` of `drive` (camera infos first).
pub(crate) async fn play(player: &Player, drive: &Drive, range: std::ops::Range<usize>) {
    player
        .camera_infos(&drive.rig, drive.frames[range.start].0)
        .await;
    for (stamp, frame) in &drive.frames[range] {
        player
            .frame(&drive.rig, *stamp, frame, &frame.left_to_world)
            .await;
    }
}

/// What one run of the node published: bin ids of its bin maps, its map updates (sequence,
/// decoded) in arrival order.
pub(crate) struct Published {
    pub(crate) bins: Vec<u64>,
    pub(crate) updates: Vec<(u64, Update)>,
}

pub(crate) fn published(collector: &Collector, keys: &Keys) -> Published {
    let bins = collector
        .headers(&keys.bin_map())
        .iter()
        .map(|h| bin_of_frame_id(&h.frame_id))
        .collect();
    let updates = collector
        .decoded::<MapUpdate>(&keys.map_update())
        .iter()
        .map(|m| (m.sequence, decode_update(m).expect("update decodes")))
        .collect();
    Published { bins, updates }
}

/// Asserts that `map` holds exactly the Gaussians subscribers hold in `published`: the same
/// ids, source bins and f64 positions, and the f32 fields as the wire carries them (opacity
/// as a logit, colour as an SH coefficient) to 1e-5.
pub(crate) fn assert_same_gaussians(map: &GlobalMap, published: &Snapshot) {
    assert_eq!(map.len(), published.gaussians.len());
    for (id, p) in &published.gaussians {
        let g = map
            .get(*id)
            .unwrap_or_else(|| panic!("Gaussian {} is in the map", id.0));
        assert_eq!(
            (g.bin_id, g.position),
            (p.bin_id, p.position),
            "Gaussian {}",
            id.0
        );
        let close = (g.opacity - p.opacity).abs() < 1e-5
            && (g.color - p.color).abs().max_element() < 1e-5
            && (g.log_scale - p.log_scale).abs().max_element() < 1e-5
            && (g.confidence - p.confidence).abs() < 1e-5
            && g.rotation.dot(p.rotation).abs() > 1.0 - 1e-5;
        assert!(close, "Gaussian {}: {g:?} vs {p:?}", id.0);
    }
}

/// The snapshot the node answers a query with, and its sequence number.
pub(crate) async fn requested_snapshot(player: &Player, keys: &Keys) -> (u64, Snapshot) {
    let replies = player.session.get(keys.snapshot_request()).await.unwrap();
    let reply = replies.recv_async().await.expect("the node answers");
    let msg = MapUpdate::decode(&reply.result().unwrap().payload().to_bytes()).unwrap();
    match decode_update(&msg).unwrap() {
        Update::Snapshot(s) => (msg.sequence, s),
        Update::Increment(_) => panic!("a query is answered with a snapshot"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_killed_mid_drive_resumes_its_map_bin_ids_and_sequence_numbers() {
    let drive = Drive::generate(
        "crash",
        &SynthConfig {
            seed: 11,
            frames: 90,
            width: 136,
            height: 40,
            ..SynthConfig::default()
        },
    );
    let poses = drive.poses();
    let all_bins = make_bins(
        &poses,
        &BinConfig {
            length_m: 8.0,
            layout: BinLayout::Consecutive,
        },
    );
    assert!(all_bins.len() >= 5, "{} bins", all_bins.len());
    // The kill comes after the first three bins were opened and published.
    let cut = all_bins[3].first;
    let (before, after) = (bins_opened(&poses[..cut]), bins_opened(&poses[cut..]));
    let out = drive.dir("out");
    let keys = Keys::new("crash");
    let listened = [keys.bin_map(), keys.map_update(), keys.diagnostics()];

    // Run 1: part of the drive, then SIGKILL once its bins are out.
    let (node, endpoint) = start_node("crash", &out, &[]).await;
    let collector = Collector::at(&endpoint, &listened, usize::MAX).await;
    let player = Player::at(&endpoint, keys.clone()).await;
    play(&player, &drive, 0..cut).await;
    assert!(
        collector.wait_count(&keys.bin_map(), before).await,
        "{before} bins before the kill: {}",
        node.stderr()
    );
    node.kill_9();
    let first = published(&collector, &keys);
    assert_eq!(first.bins, (0..before as u64).collect::<Vec<_>>());
    let mut replica = MapReplica::new();
    for (i, (sequence, update)) in first.updates.iter().enumerate() {
        assert_eq!(
            *sequence,
            i as u64 + 1,
            "a new map's updates are increments 1, 2, ..."
        );
        let Update::Increment(inc) = update else {
            panic!("a new map publishes no snapshot before its first increment")
        };
        replica.apply(inc).unwrap();
    }
    let last_sequence = first.updates.len() as u64;
    assert_eq!(last_sequence, before as u64);
    assert!(
        replica.len() > 100,
        "{} Gaussians before the kill",
        replica.len()
    );
    let max_id_before = replica.gaussians().map(|(id, _)| id.0).max().unwrap();
    // Everything published is in the checkpoint the kill left: its base and journal (the
    // kill came between journal records and their compaction into the base).
    let journal = node::fusion::segments(&out.join("global_map.journal")).unwrap();
    assert_eq!(journal.len(), 1, "one journal segment");
    let saved = restore(&out, AtTornTail::Cut)
        .unwrap()
        .expect("a checkpoint")
        .map;
    assert_same_gaussians(&saved, &replica.snapshot());
    assert_eq!(saved.last_bin_id(), Some(before as u64 - 1));
    assert_eq!(saved.increments(), last_sequence);
    // `export` reads the checkpoint the same way, without changing its files.
    let exported = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
        .args(["export", "--map"])
        .arg(out.join("global_map.ssgmap"))
        .arg("--out")
        .arg(out.join("after_kill.ply"))
        .output()
        .unwrap();
    assert!(exported.status.success(), "{exported:?}");
    let summary: serde_json::Value = serde_json::from_slice(&exported.stdout).unwrap();
    assert_eq!(summary["gaussians"], replica.len() as u64);
    assert_eq!(
        node::fusion::segments(&out.join("global_map.journal")).unwrap(),
        journal
    );
    drop((collector, player));

    // Run 2 on the same --out: it resumes, answers queries with the resumed map, and the
    // rest of the drive continues ids and sequence numbers.
    let (node, endpoint) = start_node("crash", &out, &[]).await;
    let collector = Collector::at(&endpoint, &listened, usize::MAX).await;
    let player = Player::at(&endpoint, keys.clone()).await;
    let (sequence, snapshot) = requested_snapshot(&player, &keys).await;
    assert_eq!(sequence, last_sequence);
    assert_eq!(snapshot.gaussians, replica.snapshot().gaussians);
    assert_eq!(snapshot.last_bin_id, Some(before as u64 - 1));
    play(&player, &drive, cut..drive.frames.len()).await;
    assert!(
        collector.wait_count(&keys.bin_map(), after).await,
        "{after} bins after the restart: {}",
        node.stderr()
    );
    let (status, stdout, stderr) = node.terminate();
    assert!(status.success(), "{stderr}");
    assert!(stderr.contains("resumed the global map"), "{stderr}");
    let summary: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(summary["bins_published"], after as u64);

    let second = published(&collector, &keys);
    let first_new_bin = before as u64;
    assert_eq!(
        second.bins,
        (first_new_bin..first_new_bin + after as u64).collect::<Vec<_>>(),
        "bin ids continue after the last published one"
    );
    let (updates, resumed) = (&second.updates, &second.updates[0]);
    let Update::Snapshot(resumed_snapshot) = &resumed.1 else {
        panic!("a resumed map's first update is its snapshot")
    };
    assert_eq!(resumed.0, last_sequence);
    assert_eq!(resumed_snapshot.gaussians, replica.snapshot().gaussians);
    let mut removed_later = BTreeSet::new();
    for (i, (sequence, update)) in updates[1..].iter().enumerate() {
        assert_eq!(
            *sequence,
            last_sequence + 1 + i as u64,
            "sequence numbers continue"
        );
        let Update::Increment(inc) = update else {
            panic!("increments follow the resumed snapshot")
        };
        assert!(
            inc.added.iter().all(|(id, _)| id.0 > max_id_before),
            "no id reused"
        );
        removed_later.extend(inc.removed.iter().copied());
        replica.apply(inc).unwrap();
    }
    assert_eq!(updates.len() - 1, after);

    // The final map is what subscribers hold; it keeps every Gaussian published before the
    // kill that no later bin replaced (and some did stay).
    let last = GlobalMap::load(out.join("global_map.ssgmap")).unwrap();
    let journal = node::fusion::segments(&out.join("global_map.journal")).unwrap();
    assert!(
        journal.is_empty(),
        "a clean stop folds the journal in: {journal:?}"
    );
    assert_same_gaussians(&last, &replica.snapshot());
    assert_eq!(last.increments(), last_sequence + after as u64);
    assert_eq!(last.epoch(), 1);
    let kept: Vec<GaussianId> = resumed_snapshot
        .gaussians
        .iter()
        .map(|(id, _)| *id)
        .filter(|id| !removed_later.contains(id))
        .collect();
    assert!(kept.iter().all(|&id| last.get(id).is_some()));
    assert!(kept.len() > 100, "{} Gaussians of run 1 kept", kept.len());
    eprintln!(
        "bins {before} before the kill, {after} after; {} Gaussians published before it, {} \
         of them in the final map of {}; sequence {last_sequence} -> {}",
        resumed_snapshot.gaussians.len(),
        kept.len(),
        last.len(),
        last.increments()
    );
    let diagnostics = collector.decoded::<Diagnostics>(&keys.diagnostics());
    let epoch = diagnostics.last().and_then(|d| {
        d.counters
            .iter()
            .find(|c| c.kind == "map/epoch")
            .map(|c| c.count)
    });
    assert_eq!(
        epoch,
        Some(1),
        "the diagnostics say the map was resumed once"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_checkpoint_that_does_not_load_stops_the_node_and_fresh_moves_it_aside_and_writes_no_empty_one(
) {
    let out = std::env::temp_dir().join(format!("stereosplat-crash-bad-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    let checkpoint = out.join("global_map.ssgmap");
    let junk = b"SSGMAP\0\n\x02\0\0\0 cut off by a crash".to_vec();
    std::fs::write(&checkpoint, &junk).unwrap();

    let endpoint = format!("tcp/127.0.0.1:{}", drive_support::free_port());
    let out_arg = out.to_str().unwrap();
    let args = [
        "run", "--listen", &endpoint, "--method", "sgm", "--out", out_arg,
    ];
    let (status, _, stderr) = Child::spawn(&args).wait();
    assert!(!status.success());
    assert!(stderr.contains(checkpoint.to_str().unwrap()), "{stderr}");
    assert!(
        stderr.contains("checksum") && stderr.contains("--fresh"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&checkpoint).unwrap(), junk, "left as it was");

    let (node, _) = start_node("crash_fresh", &out, &["--fresh"]).await;
    let (status, _, stderr) = node.terminate();
    assert!(status.success(), "{stderr}");
    let aside: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_str().unwrap().contains("global_map.ssgmap.replaced-"))
        .collect();
    assert_eq!(aside.len(), 1, "{stderr}");
    assert_eq!(std::fs::read(&aside[0]).unwrap(), junk);
    // The fresh node received nothing, so it leaves no (empty) checkpoint behind.
    assert!(!checkpoint.exists(), "{stderr}");
    let _ = std::fs::remove_dir_all(&out);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_recorder_killed_with_sigkill_leaves_a_recording_that_replays() {
    let dir = std::env::temp_dir().join(format!("stereosplat-crash-rec-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("killed.mcap");
    let port = drive_support::free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let keys = Keys::new("crash_rec");
    let path_arg = path.to_str().unwrap();
    let recorder = Child::spawn(&[
        "record",
        "--listen",
        &endpoint,
        "--namespace",
        "crash_rec",
        "--out",
        path_arg,
    ]);
    let ready = wait_for(Duration::from_secs(60), || {
        recorder.stderr().contains("recorder ready")
            && std::net::TcpStream::connect(("127.0.0.1", port)).is_ok()
    })
    .await;
    assert!(ready, "{}", recorder.stderr());
    let session = open(&drive_support::client_of(&endpoint)).await.unwrap();
    assert!(drive_support::net_support::sees_a_subscriber(&session, &keys.pose()).await);
    const SENT: u64 = 150;
    let publish = |range: std::ops::Range<u64>| {
        let (session, key) = (&session, keys.pose());
        async move {
            for i in range {
                let pose = glam::DAffine3::from_translation(glam::DVec3::new(i as f64, 0.0, 0.0));
                let msg = pose_from_affine(&pose, Header::new(i as i64 * 100_000_000, "world"));
                let put = session.put(&key, msg.encode());
                put.congestion_control(CongestionControl::Block)
                    .await
                    .unwrap();
            }
        }
    };
    publish(0..SENT).await;
    // The recorder closes a chunk every second: wait until every message is in one, then
    // send as many again and kill it at once, mid-chunk.
    let flushed = wait_for(Duration::from_secs(60), || {
        BagReader::recover(&path).is_ok_and(|(_, r)| r.messages == SENT)
    })
    .await;
    assert!(flushed, "{}", recorder.stderr());
    publish(SENT..2 * SENT).await;
    recorder.kill_9();
    assert!(
        BagReader::open(&path).is_err(),
        "the killed recorder did not finish the file"
    );

    let replay_endpoint = format!("tcp/127.0.0.1:{}", drive_support::free_port());
    let (status, stdout, stderr) = Child::spawn(&[
        "replay",
        "--mcap",
        path_arg,
        "--as-fast-as-possible",
        "--warmup",
        "0",
        "--listen",
        &replay_endpoint,
        "--namespace",
        "crash_rec",
    ])
    .wait();
    assert!(status.success(), "{stderr}");
    let number_after = |text: &str, word: &str| -> u64 {
        let at = text
            .find(word)
            .unwrap_or_else(|| panic!("`{word}` in {text}"))
            + word.len();
        let digits: String = text[at..]
            .chars()
            .take_while(char::is_ascii_digit)
            .collect();
        digits.parse().unwrap()
    };
    let recovered = number_after(&stderr, "recovered ");
    assert!((SENT..=2 * SENT).contains(&recovered), "{stderr}");
    assert!(stderr.contains("ignored the last"), "{stderr}");
    eprintln!("{}", stderr.trim());
    assert_eq!(number_after(&stdout, "replayed "), recovered, "{stdout}");
    let _ = std::fs::remove_dir_all(&dir);
}
