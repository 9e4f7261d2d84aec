//! The node's counters (bad input, drops), published as Diagnostics.

use std::collections::BTreeMap;

use crate::msg::latency::{Counter, Diagnostics};

/// Named counters, kept in name order so every Diagnostics message lists them the same way.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counters(BTreeMap<String, u64>);

impl Counters {
    /// Adds `n` to counter `kind`.
    pub fn add(&mut self, kind: &str, n: u64) {
        match self.0.get_mut(kind) {
            Some(v) => *v += n,
            None => _ = self.0.insert(kind.to_string(), n),
        }
    }

    /// Sets counter `kind` (for counters kept elsewhere, such as the synchroniser's).
    pub fn set(&mut self, kind: &str, n: u64) {
        // A counter set again (most are, once per sample) costs no allocation.
        match self.0.get_mut(kind) {
            Some(v) => *v = n,
            None => _ = self.0.insert(kind.to_string(), n),
        }
    }

    /// Sets every counter of `other` to its value there (counters kept by another part of
    /// the node, such as the input thread's).
    pub fn set_all(&mut self, other: &Counters) {
        for (k, v) in &other.0 {
            self.set(k, *v);
        }
    }

    /// The value of `kind` (0 if never counted).
    pub fn get(&self, kind: &str) -> u64 {
        self.0.get(kind).copied().unwrap_or(0)
    }

    /// Every counter whose name starts with `prefix`, summed.
    pub fn sum(&self, prefix: &str) -> u64 {
        self.0
            .iter()
            .filter(|(k, _)| k.starts_with(prefix))
            .map(|(_, v)| v)
            .sum()
    }

    /// As a Diagnostics message stamped `stamp_ns`.
    pub fn diagnostics(&self, stamp_ns: i64) -> Diagnostics {
        Diagnostics {
            stamp_ns,
            counters: self
                .0
                .iter()
                .map(|(kind, &count)| Counter {
                    kind: kind.clone(),
                    count,
                })
                .collect(),
        }
    }
}
