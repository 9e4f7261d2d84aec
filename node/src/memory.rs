//! The process's memory: the allocator's freed memory handed back to the system, its
//! settings for a long-running node, and the resident size ([`rss_bytes`], [`peak_rss_bytes`]).
//!
//! glibc's allocator keeps freed heap pages for later allocations. On a long drive the
//! node frees large transients all the time (a compaction's copy of the base, snapshot
//! messages, a bin's tensors), and its resident size then follows the largest of them it
//! ever held rather than the map in memory. [`release_freed_memory`] returns the free pages
//! (`malloc_trim`), and a [`Releaser`] does so every few seconds on its own thread, off the
//! publish path (`docs/long-drives.md` has the measurement). On other allocators both do
//! nothing.
//!
//! The `stereosplat` binary also runs with [`ALLOCATOR_TUNABLES`]: blocks of 4 MiB and more
//! (a bin's tensors, a snapshot, a compaction's copy of the map) are mapped on their own and
//! returned to the system when freed, on transparent huge pages. glibc reads these settings
//! only as a program starts, from `GLIBC_TUNABLES`, so the binary restarts itself once with
//! them ([`restart_with_allocator_tunables`]).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Returns the allocator's free pages to the system (glibc's `malloc_trim`; a no-op
/// elsewhere).
pub fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `malloc_trim` only returns the allocator's free pages to the system; it takes
    // no pointer and is thread-safe.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// glibc's allocator settings the `stereosplat` binary runs with: blocks of 4 MiB and more
/// mapped on their own, so freeing one returns it to the system at once (glibc otherwise
/// raises this threshold to the largest block ever freed and keeps such blocks in its
/// heaps); the top of the heap given back only past 32 MiB free, so a bin's transients do
/// not grow and shrink it every time; transparent huge pages for both, which makes mapping
/// a fresh block cost one page fault per 2 MiB instead of one per 4 KiB. Without the huge
/// pages the first two cost the model 4% of its time, with them nothing measurable
/// (`docs/long-drives.md`). A glibc without one of them ignores it.
pub const ALLOCATOR_TUNABLES: &str = "glibc.malloc.mmap_threshold=4194304:\
glibc.malloc.trim_threshold=33554432:glibc.malloc.hugetlb=1";

/// The environment variable glibc reads its tunables from.
const TUNABLES_VAR: &str = "GLIBC_TUNABLES";
/// Set on the restarted program, so it knows `GLIBC_TUNABLES` is its own.
const RESTARTED_VAR: &str = "STEREOSPLAT_ALLOCATOR_RESTARTED";

/// What the program does at start about [`ALLOCATOR_TUNABLES`], given whether
/// `GLIBC_TUNABLES` and the restart's marker are set.
#[derive(Debug, PartialEq, Eq)]
enum AtStart {
    /// Unset: restart under the tunables.
    Restart,
    /// Restarted: clear both variables, so programs it starts (a launch's nodes) restart
    /// with the whole string themselves (glibc cuts the variable it read at its first `:`).
    Clear,
    /// Set by the user (even empty): their choice, kept.
    Keep,
}

fn at_start(tunables_set: bool, restarted: bool) -> AtStart {
    match (tunables_set, restarted) {
        (_, true) => AtStart::Clear,
        (false, false) => AtStart::Restart,
        (true, false) => AtStart::Keep,
    }
}

/// Replaces the running program (`exec`, same arguments) with itself under
/// [`ALLOCATOR_TUNABLES`] when `GLIBC_TUNABLES` is unset; call it first thing in `main`,
/// before any thread starts. Returns `None` when no restart was wanted (the variable is set,
/// or the allocator is not glibc's), or the error of a restart that failed: the program
/// then goes on with the allocator's defaults. Set `GLIBC_TUNABLES` (empty for glibc's
/// defaults) to keep your own.
pub fn restart_with_allocator_tunables() -> Option<std::io::Error> {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        use std::os::unix::process::CommandExt;
        let set = |name| std::env::var_os(name).is_some();
        match at_start(set(TUNABLES_VAR), set(RESTARTED_VAR)) {
            AtStart::Keep => None,
            AtStart::Clear => {
                // Single-threaded at this point (the caller's contract).
                std::env::remove_var(TUNABLES_VAR);
                std::env::remove_var(RESTARTED_VAR);
                None
            }
            AtStart::Restart => {
                let mut args = std::env::args_os();
                let arg0 = args.next().unwrap_or_default();
                // `/proc/self/exe` is this very binary, even if its file was replaced since.
                let err = std::process::Command::new("/proc/self/exe")
                    .arg0(arg0)
                    .args(args)
                    .env(TUNABLES_VAR, ALLOCATOR_TUNABLES)
                    .env(RESTARTED_VAR, "1")
                    .exec();
                Some(err)
            }
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        let _ = (TUNABLES_VAR, RESTARTED_VAR, at_start);
        None
    }
}

/// Caps the allocator's arenas at one per core (glibc's default is eight per core): each
/// arena keeps what its threads freed, so with many the node's resident size grows with
/// every thread that ever held a large transient. Returns the cap set (`None` on other
/// allocators). Arenas already made stay; the node calls this as it starts. On the 2-core
/// machine this cap costs the model nothing (`docs/long-drives.md`).
pub fn limit_arenas_to_cores() -> Option<usize> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    limit_arenas(cores)
}

/// Caps the allocator's arenas at `arenas` (at least 1); `None` on other allocators or if
/// it refused.
fn limit_arenas(arenas: usize) -> Option<usize> {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        let n = arenas.clamp(1, i32::MAX as usize);
        // SAFETY: `mallopt` only changes a tuning parameter of the allocator; it takes no
        // pointer and is thread-safe.
        let ok = unsafe { libc::mallopt(libc::M_ARENA_MAX, n as libc::c_int) };
        (ok == 1).then_some(n)
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        let _ = arenas;
        None
    }
}

/// A thread that calls [`release_freed_memory`] every period until dropped.
pub struct Releaser {
    stop: Option<mpsc::Sender<()>>,
    thread: Option<JoinHandle<()>>,
    stats: Arc<ReleaseStats>,
}

/// What the releaser has done, shared with its thread.
#[derive(Default)]
struct ReleaseStats {
    releases: AtomicU64,
    longest_us: AtomicU64,
}

impl Releaser {
    /// Starts releasing every `period` (the first after one period); `None` for a zero
    /// period (the node then keeps what the allocator keeps).
    pub fn start(period: Duration) -> std::io::Result<Option<Self>> {
        if period.is_zero() {
            return Ok(None);
        }
        let (stop, stopped) = mpsc::channel::<()>();
        let stats = Arc::new(ReleaseStats::default());
        let shared = Arc::clone(&stats);
        let thread = std::thread::Builder::new()
            .name("memory-release".into())
            .spawn(move || {
                // A message or a dropped sender both end the loop.
                while let Err(RecvTimeoutError::Timeout) = stopped.recv_timeout(period) {
                    let start = Instant::now();
                    release_freed_memory();
                    let us = start.elapsed().as_micros().min(u64::MAX as u128) as u64;
                    shared.releases.fetch_add(1, Ordering::Relaxed);
                    shared.longest_us.fetch_max(us, Ordering::Relaxed);
                }
            })?;
        Ok(Some(Self {
            stop: Some(stop),
            thread: Some(thread),
            stats,
        }))
    }

    /// Its counters: releases so far and the longest one, milliseconds (rounded up).
    pub fn counts(&self) -> [(&'static str, u64); 2] {
        let s = &self.stats;
        [
            ("memory/releases", s.releases.load(Ordering::Relaxed)),
            (
                "memory/release_ms_max",
                s.longest_us.load(Ordering::Relaxed).div_ceil(1000),
            ),
        ]
    }
}

impl Drop for Releaser {
    fn drop(&mut self) {
        drop(self.stop.take());
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// This process's resident memory now, bytes (0 where /proc is missing).
pub fn rss_bytes() -> u64 {
    proc_status_kib("VmRSS:") * 1024
}

/// This process's highest resident memory so far, bytes (0 where /proc is missing).
pub fn peak_rss_bytes() -> u64 {
    proc_status_kib("VmHWM:") * 1024
}

/// Resets the peak [`peak_rss_bytes`] reports to the present resident memory (Linux:
/// writing 5 to `/proc/self/clear_refs`), so a later reading is the peak since now. False
/// where the kernel does not allow it (then the peak stays the process's since its start).
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", b"5").is_ok()
}

fn proc_status_kib(field: &str) -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix(field))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        })
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(r: &Releaser, name: &str) -> u64 {
        r.counts().iter().find(|(n, _)| *n == name).unwrap().1
    }

    #[test]
    fn a_releaser_releases_every_period_and_stops_when_dropped() {
        let r = Releaser::start(Duration::from_millis(5)).unwrap().unwrap();
        let start = Instant::now();
        while count(&r, "memory/releases") < 3 {
            assert!(start.elapsed() < Duration::from_secs(30), "no releases");
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(count(&r, "memory/release_ms_max") < 30_000);
        drop(r);
    }

    #[test]
    fn the_program_restarts_only_when_the_user_set_no_tunables() {
        assert_eq!(at_start(false, false), AtStart::Restart);
        assert_eq!(at_start(true, false), AtStart::Keep);
        assert_eq!(at_start(true, true), AtStart::Clear);
        // A marker without the tunables (a user's copy of the environment) restarts nothing.
        assert_eq!(at_start(false, true), AtStart::Clear);
        // One tunable string glibc can read: names separated by ':', no spaces.
        assert!(ALLOCATOR_TUNABLES
            .split(':')
            .all(|t| t.starts_with("glibc.malloc.") && t.split('=').count() == 2));
        assert!(!ALLOCATOR_TUNABLES.contains(char::is_whitespace));
    }

    #[test]
    fn the_arena_cap_is_one_per_core_and_clamped() {
        let cores = std::thread::available_parallelism().unwrap().get();
        assert_eq!(limit_arenas_to_cores(), Some(cores));
        assert_eq!(limit_arenas(0), Some(1));
        assert_eq!(limit_arenas(usize::MAX), Some(i32::MAX as usize));
        // Leave the test process as the node leaves itself.
        limit_arenas_to_cores();
    }

    #[test]
    fn a_zero_period_starts_nothing_and_the_longest_period_still_stops_at_once() {
        assert!(Releaser::start(Duration::ZERO).unwrap().is_none());
        // Dropping it returns (the test would hang otherwise) though no period ever ends.
        drop(Releaser::start(Duration::MAX).unwrap().unwrap());
        // The smallest period is a busy loop of releases; it still stops.
        let r = Releaser::start(Duration::from_nanos(1)).unwrap().unwrap();
        std::thread::sleep(Duration::from_millis(20));
        assert!(count(&r, "memory/releases") >= 1);
        drop(r);
    }
}
