//! Speed against accuracy as a measured trade (`stereosplat bench pareto`): operating points
//! from a TOML list ([`points`]), each run through the node worker's own path
//! ([`path::WorkerPath`]) on the same held-out bins and scored by the evaluation protocol,
//! the Pareto front of latency against quality ([`front()`]), and the table, JSON and chart
//! ([`report`]).

pub mod front;
pub mod path;
pub mod points;
pub mod report;

pub use front::{front, Better};
pub use path::WorkerPath;
pub use points::{load_points, parse_points, Availability, OperatingPoint, PointsError};
pub use report::{front_mark, table_cell, ParetoReport, PointResult, SkippedPoint};
