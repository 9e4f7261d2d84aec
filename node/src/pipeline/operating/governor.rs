//! Which operating point the next bin runs with, so that the worker keeps up with the
//! camera: the most accurate row of the table ([`super::OperatingTable`]) whose expected
//! worker time fits the latency budget, revised after every bin from the worker's own
//! recent times.
//!
//! A point's expected time is the median of its last `window` measured bins (model path and
//! render); a point not run yet is expected to take its table time (the model path) scaled
//! by how the measured points' model paths compare with theirs (the machine now against the
//! machine at calibration, the frames now against the table's size), plus the median
//! render of the last bins (renders cost about the same whichever point made the map). The governor moves down at once when the current point no longer fits
//! (expected above `fit` times the budget), and up only to a point expected within `up`
//! times the budget after `settle` bins at the current one: the gap between `up` and `fit`
//! is the hysteresis that keeps it from switching back and forth. When no point fits it runs
//! the table's fastest and counts the bins it runs that way. The budget is the contract: a
//! worker queue that fills because frames come faster than the budget says (a replay as
//! fast as possible) does not move it.
//!
//! The budget is fixed, or `auto`: the median time between the openings of the last bins,
//! which is the bin length over the current speed, as the poses that opened them say. Until
//! two bins have opened, `auto` runs the fastest point.

use std::collections::VecDeque;

use super::table::OperatingTable;

/// How much time a bin may take on the worker.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// This many milliseconds.
    Fixed(f64),
    /// The time between bin openings at the current speed.
    Auto,
}

/// Why a budget was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("latency budget `{0}`: give milliseconds (a positive number) or `auto`")]
pub struct BudgetError(pub String);

impl std::str::FromStr for Budget {
    type Err = BudgetError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s.trim() == "auto" {
            return Ok(Budget::Auto);
        }
        match s.trim().parse::<f64>() {
            Ok(ms) if ms.is_finite() && ms > 0.0 => Ok(Budget::Fixed(ms)),
            _ => Err(BudgetError(s.to_string())),
        }
    }
}

/// What a node chooses its operating points with.
#[derive(Clone, Debug, PartialEq)]
pub struct OperatingConfig {
    /// The points and their measured times and quality.
    pub table: OperatingTable,
    /// The worker time a bin may take.
    pub budget: Budget,
    /// The governor's thresholds.
    pub governor: GovernorConfig,
}

/// The governor's thresholds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GovernorConfig {
    /// Bins per point whose median is its measured time (and openings whose median interval
    /// is the `auto` budget).
    pub window: usize,
    /// A point fits when it is expected to take at most this fraction of the budget.
    pub fit: f64,
    /// The governor moves up only to a point expected within this fraction of the budget.
    pub up: f64,
    /// Bins run at a point before the governor moves up from it.
    pub settle: usize,
}

impl Default for GovernorConfig {
    /// A window of 5 bins, fit within 90% of the budget, move up within 70% after 3 bins.
    fn default() -> Self {
        Self {
            window: 5,
            fit: 0.9,
            up: 0.7,
            settle: 3,
        }
    }
}

/// The point the next bin runs with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Choice {
    /// The table row.
    pub point: usize,
    /// Whether it is expected to fit the budget (false: nothing fits, this is the fastest).
    pub fits: bool,
}

/// Chooses each bin's operating point (see the module documentation).
#[derive(Clone, Debug)]
pub struct Governor {
    config: GovernorConfig,
    budget: Budget,
    table_ms: Vec<f64>,
    fastest: usize,
    current: usize,
    times: Vec<VecDeque<f64>>,
    ratios: VecDeque<f64>,
    renders: VecDeque<f64>,
    opens: VecDeque<i64>,
    at_current: usize,
    switches: u64,
    unfit_bins: u64,
}

/// The median of a non-empty window.
fn median(values: &VecDeque<f64>) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().collect();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n % 2 {
        1 => v[n / 2],
        _ => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

fn push_bounded<T>(q: &mut VecDeque<T>, value: T, cap: usize) {
    q.push_back(value);
    while q.len() > cap.max(1) {
        q.pop_front();
    }
}

impl Governor {
    /// A governor over `table`'s rows with `budget`; it starts at the most accurate point
    /// the table says fits (with `auto`, at the fastest until the budget is known).
    pub fn new(table: &OperatingTable, budget: Budget, config: GovernorConfig) -> Self {
        let table_ms: Vec<f64> = table.rows.iter().map(|r| r.ms).collect();
        let mut g = Self {
            config,
            budget,
            fastest: table.fastest(),
            current: table.fastest(),
            times: vec![VecDeque::new(); table_ms.len()],
            table_ms,
            ratios: VecDeque::new(),
            renders: VecDeque::new(),
            opens: VecDeque::new(),
            at_current: 0,
            switches: 0,
            unfit_bins: 0,
        };
        if let Some(b) = g.budget_ms() {
            g.current = g.best_fitting(b * g.config.fit).unwrap_or(g.fastest);
        }
        g
    }

    /// The budget in milliseconds (`None`: `auto` before two bins have opened).
    pub fn budget_ms(&self) -> Option<f64> {
        match self.budget {
            Budget::Fixed(ms) => Some(ms),
            Budget::Auto => {
                let gaps: VecDeque<f64> = self
                    .opens
                    .iter()
                    .zip(self.opens.iter().skip(1))
                    .map(|(&a, &b)| (i128::from(b) - i128::from(a)) as f64 / 1e6)
                    .collect();
                (!gaps.is_empty()).then(|| median(&gaps))
            }
        }
    }

    /// The time `point` is expected to take on the worker, milliseconds.
    pub fn expected_ms(&self, point: usize) -> f64 {
        match self.times[point].is_empty() {
            false => median(&self.times[point]),
            true => {
                let scale = match self.ratios.is_empty() {
                    true => 1.0,
                    false => median(&self.ratios),
                };
                let render = match self.renders.is_empty() {
                    true => 0.0,
                    false => median(&self.renders),
                };
                self.table_ms[point] * scale + render
            }
        }
    }

    /// The most accurate point expected within `limit` ms.
    fn best_fitting(&self, limit: f64) -> Option<usize> {
        (0..self.table_ms.len()).find(|&i| self.expected_ms(i) <= limit)
    }

    /// A bin opened at `opened_ns` (the `auto` budget's clock).
    pub fn bin_opened(&mut self, opened_ns: i64) {
        if self.opens.back().is_some_and(|&last| opened_ns <= last) {
            // A clock step back: the intervals so far no longer compare with the next.
            self.opens.clear();
        }
        push_bounded(&mut self.opens, opened_ns, self.config.window + 1);
    }

    /// The point the next bin runs with, moving down or up the table first if the recent
    /// bins say so.
    pub fn choose(&mut self) -> Choice {
        let Some(budget) = self.budget_ms() else {
            return self.chosen(true);
        };
        let fit = budget * self.config.fit;
        let now = self.expected_ms(self.current);
        let target = if now > fit {
            self.best_fitting(fit).unwrap_or(self.fastest)
        } else if self.at_current >= self.config.settle {
            (0..self.current)
                .find(|&i| self.expected_ms(i) <= budget * self.config.up)
                .unwrap_or(self.current)
        } else {
            self.current
        };
        if target != self.current {
            self.current = target;
            self.switches += 1;
            self.at_current = 0;
        }
        let fits = self.expected_ms(self.current) <= fit;
        self.chosen(fits)
    }

    fn chosen(&mut self, fits: bool) -> Choice {
        self.unfit_bins += u64::from(!fits);
        Choice {
            point: self.current,
            fits,
        }
    }

    /// One bin at `point` took `model_ns` on the worker for its model path (model and
    /// self-check, what the table times) and `render_ns` for its render.
    pub fn record(&mut self, point: usize, model_ns: i64, render_ns: i64) {
        if point >= self.table_ms.len() {
            return;
        }
        let ms = |ns: i64| ns.max(0) as f64 / 1e6;
        let (model, render) = (ms(model_ns).max(1e-3), ms(render_ns));
        let window = self.config.window;
        push_bounded(&mut self.times[point], model + render, window);
        push_bounded(&mut self.ratios, model / self.table_ms[point], window);
        push_bounded(&mut self.renders, render, window);
        if point == self.current {
            self.at_current += 1;
        }
    }

    /// Times the governor changed point.
    pub fn switches(&self) -> u64 {
        self.switches
    }

    /// Bins run at the fastest point because no point was expected to fit.
    pub fn unfit_bins(&self) -> u64 {
        self.unfit_bins
    }

    /// The current point's row.
    pub fn current(&self) -> usize {
        self.current
    }
}
