//! `stereosplat bench fusion`: the global map and its journal alone, driven by synthetic bins
//! for hours of driving (no network, no model, no rendering), as JSON on stdout: whether the
//! time per bin and the memory stay flat, and how the disk use grows.
//!
//! The route: a loop of `--loop-radius` metres driven twice (the second pass fuses into the
//! first's cells), then a straight road. Every bin is `--bin-length` metres on from the last
//! and holds `--gaussians` Gaussians on and beside the road ahead of its camera, with random
//! colours and confidences (seeded, so runs repeat). Each bin is fused
//! ([`crate::fusion::GlobalMap::insert_bin`]), journaled and synced, and far tiles paged to
//! disk, as `run` does ([`crate::store::map_store::MapStore`]); the figures are reported
//! per window of bins. Fusing is timed twice: wall time, and the CPU time of the fusing
//! thread, which leaves out the moments a shared machine gave its core to something else.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use glam::{DAffine3, DQuat, DVec3, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::{Gaussian, GaussianSet};
use serde::Serialize;

use crate::fusion::{AtTornTail, FusionConfig, GlobalMap};
use crate::memory::rss_bytes;
use crate::store::map_files::{restore, CHECKPOINT, JOURNAL};
use crate::store::map_store::MapStore;
use crate::store::Compaction;
use crate::store::Paging;

/// Flags of `bench fusion`.
#[derive(Args, Clone, Debug)]
pub struct BenchFusionArgs {
    /// Bins to drive (45,000 bins of 8 m: 10 hours at 10 m/s).
    #[arg(long, default_value_t = 45_000, value_parser = clap::value_parser!(u64).range(1..))]
    bins: u64,
    /// Metres between bins.
    #[arg(long, default_value_t = 8.0)]
    bin_length: f64,
    /// Gaussians per bin.
    #[arg(long, default_value_t = 1_000)]
    gaussians: usize,
    /// Radius of the loop driven twice before the straight road, metres.
    #[arg(long, default_value_t = 300.0)]
    loop_radius: f64,
    /// The map's Gaussian budget.
    #[arg(long, default_value_t = FusionConfig::default().max_gaussians)]
    max_gaussians: usize,
    /// Bins per reported window.
    #[arg(long, default_value_t = 1_000, value_parser = clap::value_parser!(u64).range(1..))]
    window: u64,
    /// Fold the journal into the base at this many MiB (as `run --compact-after-mib`).
    #[arg(long, default_value_t = 64)]
    compact_after_mib: u64,
    /// Keep in memory the tiles within this many metres (as `run --page-radius-m`; 0: the
    /// whole map, evicting past the budget).
    #[arg(long, default_value_t = Paging::default().radius_m)]
    page_radius_m: f64,
    /// Folder of the map's checkpoint (emptied first).
    #[arg(long, default_value = "out/bench_fusion")]
    out: PathBuf,
}

/// One window of bins.
#[derive(Serialize)]
struct Window {
    last_bin: u64,
    fuse_p50_ms: f64,
    fuse_cpu_p50_ms: f64,
    fuse_max_ms: f64,
    journal_p50_ms: f64,
    journal_max_ms: f64,
    map_gaussians: usize,
    map_total: u64,
    evicted: usize,
    rss_mib: f64,
    disk_mib: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len().saturating_sub(1) / 2).copied().unwrap_or(0.0)
}

/// The camera's pose at bin `k`: twice around the loop (centred so it starts at the origin
/// heading +x), then straight on along +x from where the loop closes.
fn pose_at(k: u64, args: &BenchFusionArgs) -> DAffine3 {
    let s = k as f64 * args.bin_length;
    let lap = std::f64::consts::TAU * args.loop_radius;
    let (position, heading) = if s < 2.0 * lap {
        let a = s / args.loop_radius;
        let p = DVec3::new(
            args.loop_radius * a.sin(),
            args.loop_radius * (1.0 - a.cos()),
            0.0,
        );
        (p, a)
    } else {
        (DVec3::new(s - 2.0 * lap, 0.0, 0.0), 0.0)
    };
    DAffine3::from_rotation_translation(DQuat::from_rotation_z(heading), position)
}

/// A bin's Gaussians in its frame (x ahead, y left, z up): the road and its sides over the
/// next bin length, up to 3 m high.
fn bin_set(rng: &mut ChaCha8Rng, args: &BenchFusionArgs) -> GaussianSet {
    let mut set = GaussianSet::default();
    for _ in 0..args.gaussians {
        set.push(Gaussian {
            mean: Vec3::new(
                rng.random_range(0.0..args.bin_length as f32),
                rng.random_range(-10.0..10.0),
                rng.random_range(-1.6..1.4),
            ),
            log_scale: Vec3::splat(rng.random_range(0.02f32..0.2).ln()),
            rotation: Quat::IDENTITY,
            opacity: rng.random_range(0.3..1.0),
            color: Vec3::new(rng.random(), rng.random(), rng.random()),
            confidence: rng.random_range(0.0..1.0),
        });
    }
    set
}

/// Bytes of the files under `dir`.
fn disk_bytes(dir: &Path) -> u64 {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    entries
        .filter_map(Result::ok)
        .map(|e| match e.file_type() {
            Ok(t) if t.is_dir() => disk_bytes(&e.path()),
            _ => e.metadata().map_or(0, |m| m.len()),
        })
        .sum()
}

/// Runs the benchmark and prints one JSON object.
pub fn run(args: &BenchFusionArgs) -> Result<()> {
    anyhow::ensure!(
        args.window > 0 && args.bins > 0,
        "--bins and --window must be positive"
    );
    let _ = std::fs::remove_dir_all(&args.out);
    std::fs::create_dir_all(&args.out)?;
    let mut map = GlobalMap::new(FusionConfig {
        max_gaussians: args.max_gaussians,
        ..FusionConfig::default()
    })?;
    let compaction = Compaction {
        min_bytes: args.compact_after_mib.saturating_mul(1 << 20),
    };
    let paging = (args.page_radius_m > 0.0).then_some(Paging {
        radius_m: args.page_radius_m,
    });
    let mut store = MapStore::new(args.out.clone(), &map, 1, compaction, paging)?;
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let mut windows = Vec::new();
    let (mut fuse, mut fuse_cpu, mut journal, mut evicted) =
        (Vec::new(), Vec::new(), Vec::new(), 0);
    let mib = |b: u64| b as f64 / (1 << 20) as f64;
    let started = Instant::now();
    for k in 0..args.bins {
        let set = bin_set(&mut rng, args);
        let pose = pose_at(k, args);
        let (t, cpu) = (Instant::now(), thread_cpu_s());
        store.prepare(&mut map, pose.translation)?;
        let inc = map.insert_bin(k, &set, pose)?;
        fuse.push(t.elapsed().as_secs_f64() * 1e3);
        fuse_cpu.push((thread_cpu_s() - cpu) * 1e3);
        let t = Instant::now();
        store.record(&mut map, &inc)?;
        journal.push(t.elapsed().as_secs_f64() * 1e3);
        evicted += inc.stats.evicted;
        if (k + 1) % args.window == 0 || k + 1 == args.bins {
            windows.push(Window {
                last_bin: k,
                fuse_p50_ms: median(fuse.clone()),
                fuse_cpu_p50_ms: median(fuse_cpu.clone()),
                fuse_max_ms: fuse.iter().copied().fold(0.0, f64::max),
                journal_p50_ms: median(journal.clone()),
                journal_max_ms: journal.iter().copied().fold(0.0, f64::max),
                map_gaussians: map.len(),
                map_total: map.total_len(),
                evicted,
                rss_mib: mib(rss_bytes()),
                disk_mib: mib(disk_bytes(&args.out)),
            });
            (fuse, fuse_cpu, journal, evicted) = (Vec::new(), Vec::new(), Vec::new(), 0);
        }
    }
    let drive_s = started.elapsed().as_secs_f64();
    store.finish()?;
    let counts: Vec<(&str, u64)> = store.counts().to_vec();
    drop(store);
    let t = Instant::now();
    let base = GlobalMap::load(args.out.join(CHECKPOINT))?;
    let base_load_s = t.elapsed().as_secs_f64();
    drop(base);
    let journal_mib = mib(disk_bytes(&args.out.join(JOURNAL)));
    let t = Instant::now();
    let restored = restore(&args.out, AtTornTail::Stop)?.context("no checkpoint")?;
    let restore_s = t.elapsed().as_secs_f64();
    anyhow::ensure!(
        restored.map.to_bytes() == map.to_bytes(),
        "the restored map differs from the live one"
    );
    // The median of the first tenth of the windows' medians against the last tenth's.
    let tenth = (windows.len() / 10).max(1);
    let last_over_first = |f: fn(&Window) -> f64| {
        let first = median(windows[..tenth].iter().map(f).collect());
        let last = median(windows[windows.len() - tenth..].iter().map(f).collect());
        last / first.max(1e-9)
    };
    let out = serde_json::json!({
        "bins": args.bins,
        "bin_length_m": args.bin_length,
        "gaussians_per_bin": args.gaussians,
        "loop_radius_m": args.loop_radius,
        "max_gaussians": args.max_gaussians,
        "drive_s": drive_s,
        "fuse_p50_last_over_first": last_over_first(|w| w.fuse_p50_ms),
        "fuse_cpu_p50_last_over_first": last_over_first(|w| w.fuse_cpu_p50_ms),
        "counters": counts.into_iter().collect::<std::collections::BTreeMap<_, _>>(),
        "restore_s": restore_s,
        "restore_base_load_s": base_load_s,
        "restore_journal_mib": journal_mib,
        "restored_equals_live": true,
        "windows": windows,
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}

/// CPU time the calling thread has used, seconds (0 where the clock is unavailable).
fn thread_cpu_s() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `clock_gettime` writes one `timespec` through the valid pointer it is given.
    let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) } == 0;
    if ok {
        t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
    } else {
        0.0
    }
}
