//! Percentiles of the node's per-bin latency ([`BinLatency`] messages), for `monitor`, the
//! demo's summary and `bench node`.
//!
//! Every [`BinLatency`] gives up to twelve stage durations (nanoseconds on the node's clock):
//!
//! | stage | from | to |
//! | --- | --- | --- |
//! | `arrival_to_publish` | first frame arrival | map published |
//! | `wait` | first frame arrival | model start (sync, binning and the worker queue) |
//! | `model` | model start | model end |
//! | `render` | model end | render end |
//! | `before_close_margin` | map published | bin close |
//! | `map_fusion` | model end | map fused into the global map and journaled |
//! | `publish` | map fused | map published |
//! | `base` | model start | G_base done (progressive pass only, as the next four) |
//! | `pseudo_render` | G_base done | pseudo views rendered |
//! | `enhance` | pseudo views rendered | pseudo views enhanced |
//! | `plus` | pseudo views enhanced | pseudo pairs through the network |
//! | `fuse` | pseudo pairs done | G_base and G_plus fused |
//!
//! A stage is left out for a bin when either of its stamps is 0 (the bin never reached it).
//! `map_fusion` and `publish` split what the node does with a bin's map before a subscriber
//! has it; the render runs beside them on the worker.
//! `before_close_margin` is not a latency but a margin: the bin's first stereo pair goes to
//! the worker as soon as the bin opens, so its map is normally published before the frame
//! that closes the bin (8 m later) arrives, and the margin says how long before. A negative
//! margin means the map came out after its bin closed: the worker was slower than the drive.
//! Its summary ([`MarginSummary`]) reports the low tail (p10, p1, min), where trouble shows.
//!
//! Beside the stages it counts the bins' self-check verdicts and what the node did about
//! failures ([`CheckCounts`]), so `monitor` shows how many maps were flagged or replaced.
//!
//! Percentiles are nearest-rank: the p-th percentile of n sorted values is the value at rank
//! `ceil(p / 100 * n)` (1-based), so it is always one of the measured values; p100 is the
//! maximum. Every duration is kept (8 bytes per stage and bin), so memory grows with the
//! number of bins, about 40 MB per million bins.

use std::fmt;

use std::collections::BTreeMap;

use serde::Serialize;

use crate::msg::latency::BinLatency;

/// Collects [`BinLatency`] messages and summarises them per stage.
#[derive(Clone, Debug, Default)]
pub struct LatencyStats {
    bins: u64,
    /// Durations in nanoseconds, one vector per stage in [`STAGES`] order.
    durations: [Vec<i64>; STAGES.len()],
    max_queue_depth: u32,
    checks: CheckCounts,
    points: BTreeMap<String, u64>,
    last: Option<BinLatency>,
}

/// Bins by self-check verdict (`BinLatency.check_verdict`) and by what the node did about a
/// failure (`check_action`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CheckCounts {
    /// Checked and passed.
    pub pass: u64,
    /// Checked and failed.
    pub fail: u64,
    /// Too little texture to tell.
    pub undetermined: u64,
    /// Not checked (no map) or an unknown code.
    pub not_run: u64,
    /// Failed and published as they were.
    pub flagged: u64,
    /// Failed and published with opacity lowered.
    pub lowered_opacity: u64,
    /// Failed and replaced by SGM's map.
    pub fallback_sgm: u64,
    /// Replaced by SGM's map, which failed its check too.
    pub fallback_sgm_failed: u64,
}

impl CheckCounts {
    fn push(&mut self, l: &BinLatency) {
        *match l.check_verdict {
            1 => &mut self.pass,
            2 => &mut self.fail,
            3 => &mut self.undetermined,
            _ => &mut self.not_run,
        } += 1;
        match l.check_action {
            1 => self.flagged += 1,
            2 => self.lowered_opacity += 1,
            3 => {
                self.fallback_sgm += 1;
                self.fallback_sgm_failed += u64::from(l.fallback_verdict == 2);
            }
            _ => {}
        }
    }
}

/// The stamps `(from, to)` a stage runs between.
type Stamps = fn(&BinLatency) -> (i64, i64);

/// Names and stamps of the stages, in the order of the module's table.
const STAGES: [(&str, Stamps); 12] = [
    ("arrival_to_publish", |l| {
        (l.first_frame_arrival_ns, l.publish_ns)
    }),
    ("wait", |l| (l.first_frame_arrival_ns, l.model_start_ns)),
    ("model", |l| (l.model_start_ns, l.model_end_ns)),
    ("render", |l| (l.model_end_ns, l.render_end_ns)),
    ("before_close_margin", |l| (l.publish_ns, l.bin_close_ns)),
    ("map_fusion", |l| (l.model_end_ns, l.map_fused_ns)),
    ("publish", |l| (l.map_fused_ns, l.publish_ns)),
    ("base", |l| (l.model_start_ns, l.base_end_ns)),
    ("pseudo_render", |l| (l.base_end_ns, l.pseudo_render_end_ns)),
    ("enhance", |l| (l.pseudo_render_end_ns, l.enhance_end_ns)),
    ("plus", |l| (l.enhance_end_ns, l.plus_end_ns)),
    ("fuse", |l| (l.plus_end_ns, l.fuse_end_ns)),
];

/// The index of the before-close margin in [`STAGES`]: a margin, summarised by its low tail.
const MARGIN: usize = 4;

/// The stages after this index split the model's time; they are shown only when some bin
/// had the progressive pass.
const SPLIT_FROM: usize = 7;

/// Each stage's duration for one bin in nanoseconds, in [`STAGES`] order, `None` where a
/// stamp is 0.
fn stage_ns(latency: &BinLatency) -> [Option<i64>; STAGES.len()] {
    STAGES.map(|(_, stamps)| {
        let (from, to) = stamps(latency);
        (from != 0 && to != 0).then(|| to.saturating_sub(from))
    })
}

/// One bin's stage durations in milliseconds with the stages' names, in the order of the
/// module's table, `None` where the bin lacks a stamp (for a live line per bin); the
/// progressive pass's stages only when the bin had the pass.
pub fn bin_stages_ms(latency: &BinLatency) -> Vec<(&'static str, Option<f64>)> {
    stage_ns(latency)
        .into_iter()
        .enumerate()
        .filter(|(i, ns)| *i < SPLIT_FROM || ns.is_some())
        .map(|(i, ns)| (STAGES[i].0, ns.map(|ns| ns as f64 / 1e6)))
        .collect()
}

/// Seconds from the first bin's first frame (its arrival) to the last map published:
/// the span over which a run's bins per second are counted; `None` without both stamps.
pub fn publish_span_s(latencies: &[BinLatency]) -> Option<f64> {
    let first = latencies
        .iter()
        .map(|l| l.first_frame_arrival_ns)
        .filter(|&t| t > 0)
        .min()?;
    let last = latencies.iter().map(|l| l.publish_ns).max()?;
    (last > first).then(|| (last - first) as f64 / 1e9)
}

impl LatencyStats {
    /// No bins yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The statistics of `latencies` (a loopback run's, say).
    pub fn of(latencies: &[BinLatency]) -> Self {
        let mut stats = Self::new();
        for l in latencies {
            stats.push(l);
        }
        stats
    }

    /// Adds one bin's latency (in any order; bins are not deduplicated).
    pub fn push(&mut self, latency: &BinLatency) {
        self.bins += 1;
        for (duration, durations) in stage_ns(latency).into_iter().zip(&mut self.durations) {
            durations.extend(duration);
        }
        self.max_queue_depth = self.max_queue_depth.max(latency.queue_depth);
        self.checks.push(latency);
        if !latency.operating_point.is_empty() {
            *self
                .points
                .entry(latency.operating_point.clone())
                .or_default() += 1;
        }
        self.last = Some(latency.clone());
    }

    /// Bins pushed so far.
    pub fn bins(&self) -> u64 {
        self.bins
    }

    /// The percentiles of every stage so far, and the queue and counter figures.
    pub fn summary(&self) -> LatencySummary {
        let stage = |i: usize| StageSummary::of(&self.durations[i]);
        LatencySummary {
            bins: self.bins,
            arrival_to_publish: stage(0),
            wait: stage(1),
            model: stage(2),
            render: stage(3),
            before_close_margin: MarginSummary::of(&self.durations[MARGIN]),
            map_fusion: stage(5),
            publish: stage(6),
            base: stage(7),
            pseudo_render: stage(8),
            enhance: stage(9),
            plus: stage(10),
            fuse: stage(11),
            max_queue_depth: self.max_queue_depth,
            drops: self.last.as_ref().map_or(0, |l| l.drops),
            bad_messages: self.last.as_ref().map_or(0, |l| l.bad_messages),
            checks: self.checks,
            operating_points: self.points.clone(),
        }
    }
}

/// One stage's durations over the bins that reached it, in milliseconds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StageSummary {
    /// Bins with both stamps of the stage.
    pub count: usize,
    /// Median (nearest rank).
    pub p50_ms: f64,
    /// 90th percentile (nearest rank).
    pub p90_ms: f64,
    /// 99th percentile (nearest rank).
    pub p99_ms: f64,
    /// Largest.
    pub max_ms: f64,
    /// Arithmetic mean.
    pub mean_ms: f64,
}

/// Nanosecond values sorted ascending, read out in milliseconds.
struct Sorted(Vec<i64>);

impl Sorted {
    /// `values` sorted, `None` when empty.
    fn of(values: &[i64]) -> Option<Self> {
        let mut sorted = values.to_vec();
        sorted.sort_unstable();
        (!sorted.is_empty()).then_some(Self(sorted))
    }

    /// The p-th percentile by nearest rank (`ceil(p / 100 * n)`, 1-based), milliseconds.
    fn percentile_ms(&self, p: usize) -> f64 {
        let n = self.0.len();
        self.0[(p * n).div_ceil(100).max(1) - 1] as f64 / 1e6
    }

    /// The arithmetic mean, milliseconds (summed in i128, so no sum overflows).
    fn mean_ms(&self) -> f64 {
        let sum: i128 = self.0.iter().map(|&d| i128::from(d)).sum();
        sum as f64 / self.0.len() as f64 / 1e6
    }
}

impl StageSummary {
    /// The summary of `durations_ns`, `None` when it is empty.
    fn of(durations_ns: &[i64]) -> Option<Self> {
        let s = Sorted::of(durations_ns)?;
        Some(Self {
            count: s.0.len(),
            p50_ms: s.percentile_ms(50),
            p90_ms: s.percentile_ms(90),
            p99_ms: s.percentile_ms(99),
            max_ms: s.percentile_ms(100),
            mean_ms: s.mean_ms(),
        })
    }
}

/// What [`LatencyStats::summary`] reports; serialises to JSON as the field names say
/// (a stage no bin reached is `null`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LatencySummary {
    /// Bins seen.
    pub bins: u64,
    /// First frame arrival to map published: what a user of the map waits.
    pub arrival_to_publish: Option<StageSummary>,
    /// First frame arrival to model start: synchronisation, binning and the worker queue.
    pub wait: Option<StageSummary>,
    /// The reconstructor.
    pub model: Option<StageSummary>,
    /// Renders of the bin's map after the model.
    pub render: Option<StageSummary>,
    /// How long before its bin closed each map was published (negative: after).
    pub before_close_margin: Option<MarginSummary>,
    /// Model end to the map fused into the global map and journaled (tiles paged with it).
    pub map_fusion: Option<StageSummary>,
    /// Map fused to map published (the bin's messages put on the network).
    pub publish: Option<StageSummary>,
    /// The progressive pass's G_base (`null` without the pass, as the next four).
    pub base: Option<StageSummary>,
    /// Rendering the pseudo views.
    pub pseudo_render: Option<StageSummary>,
    /// The enhancer on the pseudo views.
    pub enhance: Option<StageSummary>,
    /// The pseudo pairs through the network.
    pub plus: Option<StageSummary>,
    /// Fusing G_base and G_plus.
    pub fuse: Option<StageSummary>,
    /// Largest worker queue depth any bin reported.
    pub max_queue_depth: u32,
    /// Bins dropped by the worker queue, as of the last bin pushed (the node counts since
    /// it started).
    pub drops: u64,
    /// Malformed input messages, as of the last bin pushed.
    pub bad_messages: u64,
    /// The bins' self-check verdicts and fallbacks.
    pub checks: CheckCounts,
    /// Bins per operating point (the latency messages that name one).
    pub operating_points: BTreeMap<String, u64>,
}

/// The before-close margins over the bins that have both stamps, in milliseconds: the
/// median and the low tail (nearest rank from the small end), since a small or negative
/// margin is what says the worker is falling behind.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MarginSummary {
    /// Bins with both stamps.
    pub count: usize,
    /// Median (nearest rank).
    pub p50_ms: f64,
    /// 10th percentile (nearest rank): nine bins in ten had at least this margin.
    pub p10_ms: f64,
    /// 1st percentile (nearest rank).
    pub p1_ms: f64,
    /// Smallest.
    pub min_ms: f64,
    /// Arithmetic mean.
    pub mean_ms: f64,
}

impl MarginSummary {
    /// The summary of `margins_ns`, `None` when it is empty.
    fn of(margins_ns: &[i64]) -> Option<Self> {
        let s = Sorted::of(margins_ns)?;
        Some(Self {
            count: s.0.len(),
            p50_ms: s.percentile_ms(50),
            p10_ms: s.percentile_ms(10),
            p1_ms: s.percentile_ms(1),
            min_ms: s.0[0] as f64 / 1e6,
            mean_ms: s.mean_ms(),
        })
    }
}

impl LatencySummary {
    /// Every latency stage with its name, in the order of the module's table (the
    /// before-close margin, not a latency, is [`LatencySummary::before_close_margin`]).
    pub fn stages(&self) -> [(&'static str, Option<StageSummary>); STAGES.len() - 1] {
        [
            (STAGES[0].0, self.arrival_to_publish),
            (STAGES[1].0, self.wait),
            (STAGES[2].0, self.model),
            (STAGES[3].0, self.render),
            (STAGES[5].0, self.map_fusion),
            (STAGES[6].0, self.publish),
            (STAGES[7].0, self.base),
            (STAGES[8].0, self.pseudo_render),
            (STAGES[9].0, self.enhance),
            (STAGES[10].0, self.plus),
            (STAGES[11].0, self.fuse),
        ]
    }
}

/// A text table: one row per stage (count, p50, p90, p99, max, mean in ms), then the bins,
/// queue and counter figures.
impl fmt::Display for LatencySummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:<20} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9}",
            "stage (ms)", "count", "p50", "p90", "p99", "max", "mean"
        )?;
        let progressive = self.base.is_some();
        for (i, (name, stage)) in self.stages().into_iter().enumerate() {
            if i + 1 >= SPLIT_FROM && !progressive {
                continue;
            }
            match stage {
                Some(s) => writeln!(
                    f,
                    "{name:<20} {:>6} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1}",
                    s.count, s.p50_ms, s.p90_ms, s.p99_ms, s.max_ms, s.mean_ms
                )?,
                None => writeln!(f, "{name:<20} {:>6}", 0)?,
            }
        }
        match self.before_close_margin {
            Some(m) => writeln!(
                f,
                "map out before its bin closed (ms): p50 {:.1}, p10 {:.1}, p1 {:.1}, min {:.1} \
                 over {} bins (negative: after)",
                m.p50_ms, m.p10_ms, m.p1_ms, m.min_ms, m.count
            )?,
            None => writeln!(f, "map out before its bin closed: no bin closed yet")?,
        }
        writeln!(
            f,
            "bins {}, max queue depth {}, drops {}, bad messages {}",
            self.bins, self.max_queue_depth, self.drops, self.bad_messages
        )?;
        let c = &self.checks;
        write!(
            f,
            "self-check: pass {}, fail {}, undetermined {}, not run {}; failed bins flagged {}, \
             opacity lowered {}, replaced by sgm {} (sgm failed too {})",
            c.pass,
            c.fail,
            c.undetermined,
            c.not_run,
            c.flagged,
            c.lowered_opacity,
            c.fallback_sgm,
            c.fallback_sgm_failed
        )?;
        if !self.operating_points.is_empty() {
            let points: Vec<String> = self
                .operating_points
                .iter()
                .map(|(name, n)| format!("{name} {n}"))
                .collect();
            write!(f, "\noperating points (bins): {}", points.join(", "))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    /// A bin whose stages take the given milliseconds, arriving at `t0` ms.
    fn bin(id: u64, t0: i64, wait: i64, model: i64, render: i64, close: i64) -> BinLatency {
        let arrival = t0 * MS;
        let model_start = arrival + wait * MS;
        let model_end = model_start + model * MS;
        let render_end = model_end + render * MS;
        BinLatency {
            bin_id: id,
            first_frame_arrival_ns: arrival,
            bin_close_ns: arrival + close * MS,
            model_start_ns: model_start,
            model_end_ns: model_end,
            render_end_ns: render_end,
            publish_ns: render_end + MS,
            queue_depth: id as u32 % 3,
            drops: id,
            bad_messages: 2 * id,
            ..BinLatency::default()
        }
    }

    #[test]
    fn nearest_rank_percentiles_of_known_values() {
        let mut stats = LatencyStats::new();
        // Model times 1..=10 ms, pushed out of order.
        for (i, model) in [7, 3, 10, 1, 5, 2, 9, 4, 8, 6].into_iter().enumerate() {
            stats.push(&bin(i as u64, 1000 * (i as i64 + 1), 4, model, 2, 500));
        }
        let s = stats.summary();
        assert_eq!(s.bins, 10);
        let model = s.model.unwrap();
        assert_eq!(model.count, 10);
        // Ranks ceil(0.5 * 10) = 5, ceil(0.9 * 10) = 9, ceil(0.99 * 10) = 10.
        assert_eq!(
            (model.p50_ms, model.p90_ms, model.p99_ms, model.max_ms),
            (5.0, 9.0, 10.0, 10.0)
        );
        assert_eq!(model.mean_ms, 5.5);
        let wait = s.wait.unwrap();
        assert_eq!((wait.p50_ms, wait.max_ms, wait.mean_ms), (4.0, 4.0, 4.0));
        // wait 4 + model + render 2 + publish 1.
        let total = s.arrival_to_publish.unwrap();
        assert_eq!(
            (total.p50_ms, total.max_ms, total.mean_ms),
            (12.0, 17.0, 12.5)
        );
        // The map is out 7 + model ms after arrival, the bin closes 500 ms after it.
        let margin = s.before_close_margin.unwrap();
        assert_eq!(
            (margin.p50_ms, margin.p10_ms, margin.min_ms),
            (487.0, 483.0, 483.0)
        );
        assert_eq!(s.max_queue_depth, 2);
        // The last bin pushed was bin 9.
        assert_eq!((s.drops, s.bad_messages), (9, 18));
    }

    #[test]
    fn stages_with_zero_stamps_are_left_out() {
        let mut stats = LatencyStats::new();
        let mut unfinished = bin(0, 100, 5, 20, 0, 300);
        unfinished.publish_ns = 0;
        unfinished.bin_close_ns = 0;
        stats.push(&unfinished);
        let mut never_started = bin(1, 200, 0, 0, 0, 0);
        never_started.model_start_ns = 0;
        never_started.model_end_ns = 0;
        never_started.render_end_ns = 0;
        never_started.publish_ns = 0;
        stats.push(&never_started);
        let s = stats.summary();
        assert_eq!(s.bins, 2);
        assert_eq!(s.arrival_to_publish, None);
        assert_eq!(s.before_close_margin, None);
        assert_eq!(s.wait.unwrap().count, 1);
        assert_eq!(s.model.unwrap().p50_ms, 20.0);
        // render_end == model_end: a zero-length render stage is still a stage.
        assert_eq!(s.render.unwrap().max_ms, 0.0);
        let json = serde_json::to_value(&s).unwrap();
        assert!(json["arrival_to_publish"].is_null());
        assert_eq!(json["model"]["p99_ms"], 20.0);
        assert!(s.to_string().contains("model"));
    }

    #[test]
    fn bins_are_counted_per_operating_point() {
        let mut stats = LatencyStats::new();
        for (id, point) in [(0, "tiny"), (1, "tiny-scale0.5"), (2, "tiny"), (3, "")] {
            let mut b = bin(id, 100 * id as i64, 1, 2, 3, 400);
            b.operating_point = point.into();
            stats.push(&b);
        }
        let s = stats.summary();
        let counts: Vec<(&str, u64)> = s
            .operating_points
            .iter()
            .map(|(k, &v)| (k.as_str(), v))
            .collect();
        assert_eq!(counts, [("tiny", 2), ("tiny-scale0.5", 1)]);
        assert!(s
            .to_string()
            .contains("operating points (bins): tiny 2, tiny-scale0.5 1"));
        let json = serde_json::to_value(&s).unwrap();
        assert_eq!(json["operating_points"]["tiny"], 2);
        assert!(!LatencyStats::new()
            .summary()
            .to_string()
            .contains("operating"));
    }

    #[test]
    fn an_empty_summary_has_no_stages() {
        let s = LatencyStats::new().summary();
        assert_eq!(s.bins, 0);
        assert!(s.stages().iter().all(|(_, stage)| stage.is_none()));
    }

    #[test]
    fn one_bins_stages_in_milliseconds() {
        let mut l = bin(0, 10, 3, 40, 0, 100);
        l.bin_close_ns = 0;
        let stages = bin_stages_ms(&l);
        assert_eq!(
            stages,
            [
                ("arrival_to_publish", Some(44.0)),
                ("wait", Some(3.0)),
                ("model", Some(40.0)),
                ("render", Some(0.0)),
                ("before_close_margin", None),
                ("map_fusion", None),
                ("publish", None),
            ]
        );
    }

    #[test]
    fn the_progressive_pass_splits_the_model_stage() {
        let mut l = bin(0, 10, 3, 40, 0, 100);
        let start = l.model_start_ns;
        [
            l.base_end_ns,
            l.pseudo_render_end_ns,
            l.enhance_end_ns,
            l.plus_end_ns,
            l.fuse_end_ns,
        ] = [12, 15, 15, 30, 31].map(|ms| start + ms * MS);
        // Fused half a millisecond after the model, published half a millisecond later.
        l.map_fused_ns = l.model_end_ns + MS / 2;
        let stages = bin_stages_ms(&l);
        assert_eq!(
            stages[5..],
            [
                ("map_fusion", Some(0.5)),
                ("publish", Some(0.5)),
                ("base", Some(12.0)),
                ("pseudo_render", Some(3.0)),
                ("enhance", Some(0.0)),
                ("plus", Some(15.0)),
                ("fuse", Some(1.0)),
            ]
        );
        let mut stats = LatencyStats::new();
        stats.push(&l);
        let s = stats.summary();
        assert_eq!(s.plus.unwrap().p50_ms, 15.0);
        assert!(s.to_string().contains("pseudo_render"));
        assert_eq!(s.map_fusion.unwrap().p50_ms, 0.5);
        assert!(s.to_string().contains("map_fusion"));
        // Without the pass those stages are neither listed nor printed.
        let plain = bin(1, 10, 3, 40, 0, 100);
        assert_eq!(bin_stages_ms(&plain).len(), 7);
        let mut stats = LatencyStats::new();
        stats.push(&plain);
        assert!(!stats.summary().to_string().contains("pseudo_render"));
    }

    #[test]
    fn check_verdicts_and_fallbacks_are_counted() {
        let mut stats = LatencyStats::new();
        // (verdict, action, fallback verdict)
        for (v, a, fb) in [
            (1, 0, 0),
            (2, 3, 1),
            (2, 3, 2),
            (2, 1, 0),
            (3, 0, 0),
            (0, 0, 0),
        ] {
            let mut l = bin(0, 10, 1, 1, 1, 1);
            (l.check_verdict, l.check_action, l.fallback_verdict) = (v, a, fb);
            stats.push(&l);
        }
        let c = stats.summary().checks;
        assert_eq!((c.pass, c.fail, c.undetermined, c.not_run), (1, 3, 1, 1));
        assert_eq!((c.flagged, c.lowered_opacity), (1, 0));
        assert_eq!((c.fallback_sgm, c.fallback_sgm_failed), (2, 1));
        assert!(stats
            .summary()
            .to_string()
            .contains("replaced by sgm 2 (sgm failed too 1)"));
    }

    #[test]
    fn one_bin_is_every_percentile() {
        let mut stats = LatencyStats::new();
        stats.push(&bin(3, 5, 1, 250, 0, 10));
        let model = stats.summary().model.unwrap();
        assert_eq!(
            (model.p50_ms, model.p90_ms, model.p99_ms, model.max_ms),
            (250.0, 250.0, 250.0, 250.0)
        );
    }
}
