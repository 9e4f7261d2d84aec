//! Operating points on the node: what a point is and how a TOML list of them is read
//! ([`points`]), a table of points measured on this machine ([`table`]),
//! the governor that picks each bin's point to meet a latency budget ([`governor`]), and
//! a point made runnable on the worker ([`runner`]).

pub mod governor;
pub mod points;
pub mod runner;
pub mod table;

#[cfg(test)]
mod governor_tests;

pub use governor::{Budget, BudgetError, Choice, Governor, GovernorConfig, OperatingConfig};
pub use points::{load_points, parse_points, Availability, OperatingPoint, PointsError};
pub use runner::{with_scaled_views, PointRunner};
pub use table::{OperatingTable, TableError, TableRow};
