//! Speed against accuracy as a measured trade: operating points (read by
//! [`crate::pipeline::operating::points`]) each run through the node worker's own path
//! ([`path::WorkerPath`]) on the same bins and scored by the evaluation protocol
//! ([`measure::measure_points`]), the Pareto front of latency against quality ([`front()`]),
//! and the table, JSON and chart ([`report`]). `stereosplat bench pareto` reports them; the
//! latency budget's `auto` table is measured with them.

pub mod front;
pub mod measure;
pub mod path;
pub mod report;

pub use front::{front, Better};
pub use measure::{measure_points, Measured};
pub use path::WorkerPath;
pub use report::{front_mark, table_cell, ParetoReport, PointResult, SkippedPoint};
