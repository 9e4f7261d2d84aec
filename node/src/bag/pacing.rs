//! Replay pacing: when each recorded message is due, relative to when the replay started.

use std::time::{Duration, Instant};

use super::BagError;

/// How fast a replay runs relative to the recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rate {
    /// Keep the recorded gaps between messages.
    Recorded,
    /// Run this many times faster than recorded (2.0 halves the gaps, 0.5 doubles them).
    Factor(f64),
    /// Publish every message as soon as it is read.
    AsFastAsPossible,
}

impl Rate {
    /// When a message logged `since_first_ns` after the first message is due, measured from
    /// the start of the replay. A pure function of the rate; never panics (a factor that is
    /// not finite and positive is rejected by [`Pacer::new`], here it means "not paced").
    pub fn due_after(self, since_first_ns: u64) -> Duration {
        let recorded = Duration::from_nanos(since_first_ns);
        match self {
            Rate::Recorded => recorded,
            Rate::Factor(factor) if factor.is_finite() && factor > 0.0 => {
                Duration::try_from_secs_f64(recorded.as_secs_f64() / factor)
                    .unwrap_or(Duration::MAX)
            }
            Rate::Factor(_) | Rate::AsFastAsPossible => Duration::ZERO,
        }
    }
}

/// Tells a replay loop how long to wait before publishing each message so that messages go
/// out at their recorded log times (scaled by the [`Rate`]) after the replay's start.
///
/// It measures every message from the same start instead of from the previous message, so
/// time spent reading and publishing does not accumulate into drift.
#[derive(Debug, Clone, Copy)]
pub struct Pacer {
    rate: Rate,
    start: Instant,
    first_log_time_ns: u64,
}

impl Pacer {
    /// A pacer for a replay that started at `start` (a monotonic clock reading) and whose
    /// first message was logged at `first_log_time_ns`, the bag's first log time.
    pub fn new(rate: Rate, start: Instant, first_log_time_ns: u64) -> Result<Self, BagError> {
        if let Rate::Factor(factor) = rate {
            if !(factor.is_finite() && factor > 0.0) {
                return Err(BagError::BadRate(factor));
            }
        }
        Ok(Self {
            rate,
            start,
            first_log_time_ns,
        })
    }

    /// How long to sleep, at clock reading `now`, before publishing a message logged at
    /// `log_time_ns`: zero if it is already due (or logged before the first message).
    pub fn delay(&self, log_time_ns: u64, now: Instant) -> Duration {
        let since_first = log_time_ns.saturating_sub(self.first_log_time_ns);
        let due = self.rate.due_after(since_first);
        match self.start.checked_add(due) {
            Some(at) => at.saturating_duration_since(now),
            None => Duration::MAX,
        }
    }

    /// Sleeps the current thread until the message logged at `log_time_ns` is due.
    pub fn wait(&self, log_time_ns: u64) {
        let delay = self.delay(log_time_ns, Instant::now());
        if !delay.is_zero() {
            std::thread::sleep(delay);
        }
    }
}
