//! Resident memory sampled every second of a `bench drive`, each sample marked with whether
//! the map's journal was being folded into its base then (a compaction: the compactor holds a
//! second copy of the map in memory for a few seconds), so the drive's memory can be read
//! apart from that bounded, periodic transient.
//!
//! A compaction is seen from the journal's folder: the segment being folded stays there
//! until the base is rewritten, beside the one the next bins are written to, so two segments
//! or more mean a compaction is under way; and the oldest segment changing since the last
//! sample means one ended within that second (it may have begun and ended between two
//! samples). The folder shows a compaction up to a bin late: the closed segment stays alone
//! until the next bin's record opens the next one, while the compactor has already begun
//! reading the base. So the sample before the first that shows one counts as in it too.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Result;
use serde::Serialize;

use crate::fusion::segments;
use crate::memory::rss_bytes;

/// How often the trace samples.
const PERIOD: Duration = Duration::from_secs(1);

/// One sample.
#[derive(Clone, Copy, Debug)]
pub struct RssSample {
    /// Seconds since the trace started.
    pub seconds: f64,
    /// Frames replayed by then.
    pub frame: usize,
    /// The process's resident memory, bytes.
    pub bytes: u64,
    /// Whether a compaction was under way.
    pub compacting: bool,
}

/// The samples of a drive and the journal folder they watch.
pub struct RssTrace {
    journal: PathBuf,
    start: Instant,
    last: Option<Instant>,
    /// The oldest segment at the last sample.
    oldest: Option<PathBuf>,
    samples: Vec<RssSample>,
}

/// The largest resident memory from a frame on, outside compactions and during them, MiB.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct RssSplit {
    /// Largest outside compactions (`None`: no such sample).
    pub max_outside_compaction_mib: Option<f64>,
    /// Largest during compactions (`None`: no compaction was sampled).
    pub max_during_compaction_mib: Option<f64>,
    /// Samples taken during compactions (about seconds).
    pub compacting_samples: usize,
    /// All samples counted.
    pub samples: usize,
}

/// Resident memory over one minute of the trace, MiB.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MinuteRss {
    /// Which minute (0: the first).
    pub minute: usize,
    /// Samples in it.
    pub samples: usize,
    /// The smallest sample.
    pub min_mib: f64,
    /// The median sample: the level.
    pub median_mib: f64,
    /// The largest sample: the level with a bin's transient on top.
    pub max_mib: f64,
}

/// How flat resident memory stayed over the whole minutes from the second on: the largest
/// per-minute figure over the smallest, for the level (medians) and the peaks (maxima).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MinuteGrowth {
    /// Whole minutes counted (the first and a last partial one left out).
    pub minutes: usize,
    /// Largest per-minute median over the smallest.
    pub median: f64,
    /// Largest per-minute maximum over the smallest.
    pub max: f64,
    /// The last whole minute's median over the second minute's.
    pub median_last_over_second: f64,
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1 << 20) as f64
}

impl RssTrace {
    /// A trace watching the journal folder `journal`.
    pub fn new(journal: impl Into<PathBuf>) -> Self {
        Self {
            journal: journal.into(),
            start: Instant::now(),
            last: None,
            oldest: None,
            samples: Vec::new(),
        }
    }

    /// Takes a sample when a second has passed since the last one; `frame` is the frames
    /// replayed so far.
    pub fn observe(&mut self, frame: usize) {
        let now = Instant::now();
        if self.last.is_some_and(|t| now.duration_since(t) < PERIOD) {
            return;
        }
        self.last = Some(now);
        // A folder that cannot be read counts as no compaction: the sample is still kept.
        let now_segments = segments(&self.journal).unwrap_or_default();
        let oldest = now_segments.first().cloned();
        let folded = self.oldest.is_some() && oldest != self.oldest;
        let compacting = now_segments.len() >= 2 || folded;
        self.oldest = oldest;
        if compacting {
            if let Some(before) = self.samples.last_mut() {
                before.compacting = true;
            }
        }
        self.samples.push(RssSample {
            seconds: now.duration_since(self.start).as_secs_f64(),
            frame,
            bytes: rss_bytes(),
            compacting,
        });
    }

    /// The samples so far, oldest first.
    pub fn samples(&self) -> &[RssSample] {
        &self.samples
    }

    /// The largest resident memory from frame `from` on, apart and during compactions.
    pub fn split_from(&self, from: usize) -> RssSplit {
        let later = || self.samples.iter().filter(move |s| s.frame >= from);
        let max = |compacting: bool| {
            later()
                .filter(|s| s.compacting == compacting)
                .map(|s| s.bytes)
                .max()
                .map(mib)
        };
        RssSplit {
            max_outside_compaction_mib: max(false),
            max_during_compaction_mib: max(true),
            compacting_samples: later().filter(|s| s.compacting).count(),
            samples: later().count(),
        }
    }

    /// The samples summarised per minute of the trace, oldest first.
    pub fn per_minute(&self) -> Vec<MinuteRss> {
        let mut minutes: Vec<Vec<u64>> = Vec::new();
        for s in &self.samples {
            let m = (s.seconds / 60.0) as usize;
            if minutes.len() <= m {
                minutes.resize(m + 1, Vec::new());
            }
            minutes[m].push(s.bytes);
        }
        minutes
            .into_iter()
            .enumerate()
            .filter(|(_, v)| !v.is_empty())
            .map(|(minute, mut v)| {
                v.sort_unstable();
                MinuteRss {
                    minute,
                    samples: v.len(),
                    min_mib: mib(v[0]),
                    median_mib: mib(v[(v.len() - 1) / 2]),
                    max_mib: mib(v[v.len() - 1]),
                }
            })
            .collect()
    }

    /// [`MinuteGrowth`] over the minutes after the first that hold at least half a minute
    /// of samples; `None` when there are none.
    pub fn growth_after_first_minute(&self) -> Option<MinuteGrowth> {
        let whole: Vec<MinuteRss> = self
            .per_minute()
            .into_iter()
            .filter(|m| m.minute >= 1 && m.samples * 2 >= (60.0 / PERIOD.as_secs_f64()) as usize)
            .collect();
        let (first, last) = (whole.first()?, whole.last()?);
        let spread = |f: fn(&MinuteRss) -> f64| {
            let hi = whole.iter().map(f).fold(f64::MIN, f64::max);
            let lo = whole.iter().map(f).fold(f64::MAX, f64::min);
            hi / lo.max(1e-9)
        };
        Some(MinuteGrowth {
            minutes: whole.len(),
            median: spread(|m| m.median_mib),
            max: spread(|m| m.max_mib),
            median_last_over_second: last.median_mib / first.median_mib.max(1e-9),
        })
    }

    /// Writes the samples as CSV: seconds, frame, resident MiB, compacting (0 or 1).
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        let mut csv = String::from("seconds,frame,rss_mib,compacting\n");
        for s in &self.samples {
            csv += &format!(
                "{:.1},{},{:.1},{}\n",
                s.seconds,
                s.frame,
                mib(s.bytes),
                u8::from(s.compacting)
            );
        }
        std::fs::write(path, csv)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_compaction_is_marked_from_the_sample_before_it_shows_to_its_fold() {
        let dir = crate::untrusted_input::scratch_dir().join("rss_trace");
        let _ = std::fs::remove_dir_all(&dir);
        let journal = dir.join("journal");
        let mut trace = RssTrace::new(&journal);
        // No folder yet: not compacting.
        trace.observe(0);
        std::fs::create_dir_all(&journal).unwrap();
        std::fs::write(crate::fusion::segment_path(&journal, 1), b"").unwrap();
        trace.last = None;
        trace.observe(10);
        std::fs::write(crate::fusion::segment_path(&journal, 9), b"").unwrap();
        trace.last = None;
        trace.observe(20);
        // Within a second of the last sample nothing is taken.
        trace.observe(21);
        // The folded segment removed: a compaction ended within the last second.
        std::fs::remove_file(crate::fusion::segment_path(&journal, 1)).unwrap();
        trace.last = None;
        trace.observe(30);
        // The same segment alone again: outside.
        trace.last = None;
        trace.observe(40);
        let flags: Vec<bool> = trace.samples().iter().map(|s| s.compacting).collect();
        // The sample before the first that showed it counts as in the compaction.
        assert_eq!(flags, [false, true, true, true, false]);
        assert!(trace.samples().iter().all(|s| s.bytes > 0));
        let split = trace.split_from(10);
        assert_eq!((split.samples, split.compacting_samples), (4, 3));
        assert!(split.max_outside_compaction_mib.unwrap() > 0.0);
        assert!(split.max_during_compaction_mib.unwrap() > 0.0);
        // From beyond the last frame: nothing to report, no division anywhere.
        let none = trace.split_from(usize::MAX);
        assert_eq!(none.samples, 0);
        assert!(none.max_outside_compaction_mib.is_none());
        assert!(none.max_during_compaction_mib.is_none());
        let csv = dir.join("rss.csv");
        trace.write_csv(&csv).unwrap();
        let text = std::fs::read_to_string(&csv).unwrap();
        assert_eq!(text.lines().count(), 6);
        assert!(text.lines().nth(2).unwrap().ends_with(",1"));
        assert!(text.lines().last().unwrap().ends_with(",0"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn sample(seconds: f64, mib: u64) -> RssSample {
        RssSample {
            seconds,
            frame: (seconds * 10.0) as usize,
            bytes: mib << 20,
            compacting: false,
        }
    }

    #[test]
    fn minutes_summarise_level_and_peaks_and_leave_out_the_first_and_a_partial_last() {
        let mut trace = RssTrace::new("unused");
        // Minute 0 climbs; minutes 1 and 2 sit at 100 MiB with a bin's 130 MiB every 10 s
        // in minute 1 and 110 MiB in minute 2; ten seconds of minute 3 at 500 MiB.
        for s in 0..60 {
            trace.samples.push(sample(f64::from(s), 20 + s as u64));
        }
        for s in 60..180 {
            let peak = if s < 120 { 130 } else { 110 };
            trace
                .samples
                .push(sample(f64::from(s), if s % 10 == 0 { peak } else { 100 }));
        }
        for s in 180..190 {
            trace.samples.push(sample(f64::from(s), 500));
        }
        let minutes = trace.per_minute();
        assert_eq!(minutes.len(), 4);
        assert_eq!((minutes[0].min_mib, minutes[0].max_mib), (20.0, 79.0));
        assert_eq!(minutes[1].median_mib, 100.0);
        assert_eq!((minutes[1].max_mib, minutes[2].max_mib), (130.0, 110.0));
        let g = trace
            .growth_after_first_minute()
            .expect("two whole minutes");
        assert_eq!(g.minutes, 2);
        assert_eq!(g.median, 1.0);
        assert_eq!(g.median_last_over_second, 1.0);
        assert!((g.max - 130.0 / 110.0).abs() < 1e-12);
        // No whole minute after the first, or nothing resident: no ratio, or a finite one.
        let mut short = RssTrace::new("unused");
        short.samples.push(sample(5.0, 10));
        assert!(short.growth_after_first_minute().is_none());
        let mut zero = RssTrace::new("unused");
        for s in 60..120 {
            zero.samples
                .push(sample(f64::from(s), u64::from(s % 2 == 0)));
        }
        let g = zero.growth_after_first_minute().expect("one whole minute");
        assert!(g.median.is_finite() && g.max.is_finite());
    }
}
