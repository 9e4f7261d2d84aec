//! A full disk never breaks write-ahead. The `stereosplat` binary runs as a child process on
//! loopback (SGM, a generated drive) with its `--out` on a real 16 MiB tmpfs; the test fills
//! that file system in the middle of the drive, then frees it. While it is full no bin is
//! published (they are held, a bounded number, the rest dropped and counted), snapshot
//! queries are refused, and the node keeps running; once there is room the held bins go out
//! in order, and the rest of the drive follows. Killed with SIGKILL at the end, the node's
//! files restore exactly what it published, and a restart goes on from the last published
//! bin id and sequence number.
//!
//! Mounting the tmpfs needs root (CI and the developers' machines run tests as root).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use model::bins::{make_bins, BinConfig, BinLayout};
use model::synth::SynthConfig;
use node::fusion::{AtTornTail, MapReplica, Update};
use node::msg::latency::Diagnostics;
use node::store::map_files::restore;
use node::transport::Keys;

use super::drive_support::{wait_for, Collector, Drive, Player};
use super::node_crash::{assert_same_gaussians, play, published, requested_snapshot, start_node};

/// A tmpfs mounted for the test, unmounted when dropped.
pub(crate) struct Tmpfs(pub(crate) PathBuf);

impl Tmpfs {
    pub(crate) fn mount(at: PathBuf, size: &str) -> Self {
        std::fs::create_dir_all(&at).unwrap();
        let status = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(&at)
            .status()
            .expect("mount runs");
        assert!(
            status.success(),
            "mounting a tmpfs at {} failed: the test needs root (CAP_SYS_ADMIN)",
            at.display()
        );
        Self(at)
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// Fills the file system holding `dir` with one file; returns its path and size.
pub(crate) fn fill(dir: &Path) -> (PathBuf, u64) {
    let path = dir.join("ballast");
    let mut file = std::fs::File::create(&path).unwrap();
    let chunk = vec![0x5a_u8; 64 << 10];
    let mut written = 0u64;
    loop {
        match file.write(&chunk) {
            Ok(0) | Err(_) => break,
            Ok(n) => written += n as u64,
        }
    }
    (path, written)
}

/// The node's counter `name` in its last diagnostics message (0 before any).
fn counter(collector: &Collector, keys: &Keys, name: &str) -> u64 {
    let last = collector.decoded::<Diagnostics>(&keys.diagnostics()).pop();
    last.and_then(|d| d.counters.into_iter().find(|c| c.kind == name))
        .map_or(0, |c| c.count)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_disk_holds_bins_back_until_there_is_room_and_a_restart_restores_what_was_published()
{
    let drive = Drive::generate(
        "disk-full",
        &SynthConfig {
            seed: 13,
            frames: 200,
            width: 136,
            height: 40,
            ..SynthConfig::default()
        },
    );
    let poses = drive.poses();
    let config = BinConfig {
        length_m: 8.0,
        layout: BinLayout::Consecutive,
    };
    let all_bins = make_bins(&poses, &config);
    assert!(all_bins.len() >= 10, "{} bins", all_bins.len());
    // Bins the node has opened after frames `..end` (its open bin included).
    let opened = |end: usize| make_bins(&poses[..end], &config).len() + 1;
    let (cut1, cut2) = (all_bins[2].first, all_bins[8].first);
    let (before, during) = (opened(cut1), opened(cut2) - opened(cut1));
    assert!(during > node_held_at_most(), "{during} bins while full");
    let disk = Tmpfs::mount(drive.dir("tmpfs"), "16m");
    let out = disk.0.join("out");
    let keys = Keys::new("diskfull");
    let listened = [keys.bin_map(), keys.map_update(), keys.diagnostics()];
    let (node, endpoint) = start_node("diskfull", &out, &[]).await;
    let collector = Collector::at(&endpoint, &listened, usize::MAX).await;
    let player = Player::at(&endpoint, keys.clone()).await;

    // 1. Room: the first bins are journaled and published.
    play(&player, &drive, 0..cut1).await;
    assert!(
        collector.wait_count(&keys.bin_map(), before).await,
        "{before} bins with room: {}",
        node.stderr()
    );
    // 2. Full: the next bins are held (at most the node's bound) or dropped, none published.
    let (ballast, filled) = fill(&disk.0);
    play(&player, &drive, cut1..cut2).await;
    let accounted = wait_for(Duration::from_secs(120), || {
        counter(&collector, &keys, "map/held_bins")
            + counter(&collector, &keys, "dropped/not_durable")
            == during as u64
    })
    .await;
    let (held, dropped) = (
        counter(&collector, &keys, "map/held_bins"),
        counter(&collector, &keys, "dropped/not_durable"),
    );
    assert!(
        accounted,
        "{held} held, {dropped} dropped: {}",
        node.stderr()
    );
    assert_eq!(held, node_held_at_most() as u64);
    assert!(counter(&collector, &keys, "error/checkpoint") >= 1);
    assert_eq!(
        collector.count(&keys.bin_map()),
        before,
        "nothing published while full"
    );
    let refused = player.session.get(keys.snapshot_request()).await.unwrap();
    let reply = refused.recv_async().await.expect("the node answers");
    let Err(why) = reply.result() else {
        panic!("a snapshot is refused while full")
    };
    assert!(
        why.payload()
            .try_to_string()
            .unwrap()
            .contains("not durable"),
        "{why:?}"
    );
    // 3. Room again: the held bins go out, in order, then the rest of the drive.
    std::fs::remove_file(&ballast).unwrap();
    let after_room = before + held as usize;
    assert!(
        collector.wait_count(&keys.bin_map(), after_room).await,
        "the {held} held bins after room came back: {}",
        node.stderr()
    );
    play(&player, &drive, cut2..drive.frames.len()).await;
    let rest = opened(drive.frames.len()) - opened(cut2);
    let total = after_room + rest;
    assert!(
        collector.wait_count(&keys.bin_map(), total).await,
        "{total} bins in all: {}",
        node.stderr()
    );
    node.kill_9();

    let run = published(&collector, &keys);
    let first_held = before as u64;
    let mut want: Vec<u64> = (0..first_held + held).collect();
    let first_rest = first_held + during as u64;
    want.extend(first_rest..first_rest + rest as u64);
    assert_eq!(
        run.bins, want,
        "held bins in order; dropped ones never published"
    );
    let mut replica = MapReplica::new();
    for (i, (sequence, update)) in run.updates.iter().enumerate() {
        assert_eq!(*sequence, i as u64 + 1, "sequence numbers without a gap");
        let Update::Increment(inc) = update else {
            panic!("increments only")
        };
        replica.apply(inc).unwrap();
    }
    let last_sequence = run.updates.len() as u64;
    // What the kill left restores exactly what was published.
    let saved = restore(&out, AtTornTail::Cut)
        .unwrap()
        .expect("a checkpoint");
    assert_same_gaussians(&saved.map, &replica.snapshot());
    assert_eq!(saved.map.last_bin_id(), run.bins.last().copied());
    assert_eq!(saved.map.increments(), last_sequence);
    eprintln!(
        "disk filled with {filled} bytes: {before} bins published before, {held} held and \
         {dropped} dropped while full, {} published after room came back; restored {} \
         Gaussians at sequence {last_sequence}; journal replay skipped {} failed writes",
        run.bins.len() - before,
        saved.map.len(),
        saved.replay.failed_writes.len()
    );

    // A restart resumes there.
    let (node, endpoint) = start_node("diskfull", &out, &[]).await;
    let player = Player::at(&endpoint, keys.clone()).await;
    let (sequence, snapshot) = requested_snapshot(&player, &keys).await;
    assert_eq!(sequence, last_sequence);
    assert_eq!(snapshot.gaussians, replica.snapshot().gaussians);
    assert_eq!(snapshot.last_bin_id, run.bins.last().copied());
    let (status, _, stderr) = node.terminate();
    assert!(status.success(), "{stderr}");
    drop(disk);
}

/// The node's bound on held bins.
fn node_held_at_most() -> usize {
    node::service::MAX_HELD_BINS
}
