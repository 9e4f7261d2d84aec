//! Who the snapshot queryable answers. A snapshot is the whole global map (megabytes), so
//! one query of a few bytes must not be able to make the node send it over and over: the
//! node answers only queries whose key expression is exactly its snapshot key (a wildcard
//! such as `stereosplat/**` that merely matches it is refused) and at most one query per
//! interval. Refused queries are answered with an error reply naming the reason (a few
//! bytes) and counted as `refused/snapshot_key` or `refused/snapshot_rate`.

use std::time::{Duration, Instant};

/// Why a snapshot query was not answered with the map.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SnapshotRefusal {
    /// The query's key expression is not the snapshot key itself.
    #[error("snapshot queries must use exactly `{expected}`, not `{got}`")]
    Key {
        /// The snapshot key.
        expected: String,
        /// The query's key expression.
        got: String,
    },
    /// Another query was answered less than the interval ago.
    #[error("at most one snapshot per {interval:?}; retry in {retry_in:?}")]
    Rate {
        /// The interval.
        interval: Duration,
        /// How long until a query is answered again.
        retry_in: Duration,
    },
}

impl SnapshotRefusal {
    /// The counter this refusal adds to.
    pub fn counter(&self) -> &'static str {
        match self {
            SnapshotRefusal::Key { .. } => "refused/snapshot_key",
            SnapshotRefusal::Rate { .. } => "refused/snapshot_rate",
        }
    }
}

/// Decides, query by query, whether the snapshot is sent.
#[derive(Debug)]
pub struct SnapshotGate {
    key: String,
    interval: Duration,
    last_answered: Option<Instant>,
}

impl SnapshotGate {
    /// A gate for the snapshot key `key` answering once per `interval` at most.
    pub fn new(key: String, interval: Duration) -> Self {
        Self {
            key,
            interval,
            last_answered: None,
        }
    }

    /// Whether a query on `key_expr` arriving `now` gets the snapshot; an accepted query
    /// starts the next interval.
    pub fn admit(&mut self, key_expr: &str, now: Instant) -> Result<(), SnapshotRefusal> {
        if key_expr != self.key {
            return Err(SnapshotRefusal::Key {
                expected: self.key.clone(),
                got: key_expr.to_owned(),
            });
        }
        if let Some(last) = self.last_answered {
            let since = now.saturating_duration_since(last);
            if since < self.interval {
                return Err(SnapshotRefusal::Rate {
                    interval: self.interval,
                    retry_in: self.interval - since,
                });
            }
        }
        self.last_answered = Some(now);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_exact_key_once_per_interval() {
        let mut gate = SnapshotGate::new("ns/map/snapshot".into(), Duration::from_secs(1));
        let t0 = Instant::now();
        for wildcard in ["ns/**", "ns/map/*", "**"] {
            let e = gate.admit(wildcard, t0).unwrap_err();
            assert_eq!(e.counter(), "refused/snapshot_key");
        }
        assert_eq!(gate.admit("ns/map/snapshot", t0), Ok(()));
        let ms = Duration::from_millis;
        let e = gate.admit("ns/map/snapshot", t0 + ms(400)).unwrap_err();
        assert_eq!(
            e,
            SnapshotRefusal::Rate {
                interval: ms(1000),
                retry_in: ms(600)
            }
        );
        // A refused query does not restart the interval.
        assert_eq!(gate.admit("ns/map/snapshot", t0 + ms(1000)), Ok(()));
        assert!(gate.admit("ns/map/snapshot", t0 + ms(1999)).is_err());
    }
}
