//! One edge's transforms over time: the samples of a dynamic edge kept sorted by stamp within
//! the cache length and a count cap, and read at any stamp between the oldest and the newest
//! by interpolating its two neighbours (translation linearly, rotation by slerp), as tf2's
//! `TimeCache` does.

use std::collections::VecDeque;

use glam::{DQuat, DVec3};

/// One transform of an edge: child to parent at `stamp_ns`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Nanoseconds since the epoch.
    pub stamp_ns: i64,
    /// The child frame's origin in the parent frame.
    pub translation: DVec3,
    /// The child frame's orientation in the parent frame (unit).
    pub rotation: DQuat,
}

impl Sample {
    /// The sample between `self` and `later` at `stamp_ns` (which lies between their
    /// stamps): translation linear, rotation slerp on the shorter arc.
    fn interpolate(&self, later: &Sample, stamp_ns: i64) -> Sample {
        // i128: the span of two i64 stamps does not fit an i64.
        let span = later.stamp_ns as i128 - self.stamp_ns as i128;
        let t = ((stamp_ns as i128 - self.stamp_ns as i128) as f64 / span as f64).clamp(0.0, 1.0);
        Sample {
            stamp_ns,
            translation: self.translation.lerp(later.translation, t),
            rotation: self.rotation.slerp(later.rotation, t).normalize(),
        }
    }
}

/// Why a sample was not kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    /// Older than the newest sample minus the cache length (tf2's `TF_OLD_DATA`).
    TooOld {
        /// The newest stamp held.
        newest_ns: i64,
    },
    /// A sample with the same stamp is held (tf2's `TF_REPEATED_DATA`: the first is kept).
    Repeated,
}

/// Where a stamp falls against the samples held.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum At {
    /// Within the range: the transform there.
    Inside(Sample),
    /// Before the oldest sample.
    Past {
        /// The oldest stamp held.
        oldest_ns: i64,
    },
    /// After the newest sample.
    Future {
        /// The newest stamp held.
        newest_ns: i64,
    },
}

/// The samples of a dynamic edge, sorted by stamp, oldest first; never empty.
#[derive(Clone, Debug)]
pub struct TimeCache {
    samples: VecDeque<Sample>,
}

impl TimeCache {
    /// A cache holding `first`.
    pub fn new(first: Sample) -> Self {
        Self {
            samples: VecDeque::from([first]),
        }
    }

    /// Samples held.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// The oldest stamp held.
    pub fn oldest_ns(&self) -> i64 {
        self.samples.front().map_or(i64::MIN, |s| s.stamp_ns)
    }

    /// The newest stamp held.
    pub fn newest_ns(&self) -> i64 {
        self.samples.back().map_or(i64::MIN, |s| s.stamp_ns)
    }

    /// Inserts `sample` in stamp order (stamps may come in any order), then drops what is
    /// older than the newest minus `cache_ns` (a negative length counts as 0), then the
    /// oldest beyond `max_samples` (at least 1), so the newest always stays. Returns how many
    /// samples were dropped for the cap.
    pub fn insert(
        &mut self,
        sample: Sample,
        cache_ns: i64,
        max_samples: usize,
    ) -> Result<usize, Refused> {
        let cache_ns = cache_ns.max(0);
        let newest_ns = self.newest_ns();
        if sample.stamp_ns < newest_ns.saturating_sub(cache_ns) {
            return Err(Refused::TooOld { newest_ns });
        }
        let at = self
            .samples
            .partition_point(|s| s.stamp_ns < sample.stamp_ns);
        if self
            .samples
            .get(at)
            .is_some_and(|s| s.stamp_ns == sample.stamp_ns)
        {
            return Err(Refused::Repeated);
        }
        self.samples.insert(at, sample);
        let horizon = self.newest_ns().saturating_sub(cache_ns);
        while self.samples.front().is_some_and(|s| s.stamp_ns < horizon) {
            self.samples.pop_front();
        }
        let mut capped = 0;
        while self.samples.len() > max_samples.max(1) {
            self.samples.pop_front();
            capped += 1;
        }
        Ok(capped)
    }

    /// The transform at `stamp_ns`: a held sample's own at its stamp, the interpolation of
    /// its two neighbours between them, and no extrapolation (tf2 allows none).
    pub fn at(&self, stamp_ns: i64) -> At {
        let (oldest_ns, newest_ns) = (self.oldest_ns(), self.newest_ns());
        if stamp_ns < oldest_ns {
            return At::Past { oldest_ns };
        }
        if stamp_ns > newest_ns {
            return At::Future { newest_ns };
        }
        let after = self.samples.partition_point(|s| s.stamp_ns < stamp_ns);
        let later = &self.samples[after];
        if later.stamp_ns == stamp_ns || after == 0 {
            return At::Inside(*later);
        }
        At::Inside(self.samples[after - 1].interpolate(later, stamp_ns))
    }
}
