//! The node's side of a latency budget: the governor
//! ([`crate::pipeline::operating::Governor`]) is shared with the worker, which asks it for
//! each bin's point when it takes the bin and tells it how long the bin took; the node tells
//! it when bins open (the `auto` budget's clock) and counts what it did:
//! `operating/switches`, `operating/no_point_fits` (bins run at the fastest point because
//! none was expected to fit), `operating/budget_ms` and `operating/bins/<point>`. The first
//! bin for which no point fits is also said on stderr.

use std::sync::{Arc, Mutex, MutexGuard};

use crate::pipeline::operating::{Governor, OperatingConfig};
use crate::pipeline::worker::WorkerEvent;

use crate::counters::Counters;

/// The shared governor and what the node counts of it.
pub struct Pace {
    governor: Arc<Mutex<Governor>>,
    warned: bool,
}

impl Pace {
    /// A governor over `config`'s table and budget.
    pub fn new(config: &OperatingConfig) -> Self {
        Self {
            governor: Arc::new(Mutex::new(Governor::new(
                &config.table,
                config.budget,
                config.governor,
            ))),
            warned: false,
        }
    }

    /// The governor, for the worker.
    pub fn governor(&self) -> Arc<Mutex<Governor>> {
        Arc::clone(&self.governor)
    }

    fn lock(&self) -> MutexGuard<'_, Governor> {
        self.governor.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A bin opened at `opened_ns`.
    pub fn bin_opened(&self, opened_ns: i64) {
        self.lock().bin_opened(opened_ns);
    }

    /// Counts a worker event (`names` are the points', by index) and the governor's state.
    pub fn count(&mut self, event: &WorkerEvent, names: &[String], counters: &mut Counters) {
        let WorkerEvent::Map(out) = event else {
            return;
        };
        let name = names.get(out.point).map_or("", String::as_str);
        counters.add(&format!("operating/bins/{name}"), 1);
        let (switches, unfit, budget) = {
            let g = self.lock();
            (g.switches(), g.unfit_bins(), g.budget_ms())
        };
        if unfit > 0 && !self.warned {
            self.warned = true;
            eprintln!(
                "no operating point is expected to fit the latency budget ({:.0} ms): bins run \
                 at the fastest, `{name}` (counted as operating/no_point_fits)",
                budget.unwrap_or(f64::NAN),
            );
        }
        counters.set("operating/switches", switches);
        counters.set("operating/no_point_fits", unfit);
        if let Some(b) = budget {
            counters.set("operating/budget_ms", b.round() as u64);
        }
    }
}
