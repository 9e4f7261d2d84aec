//! Benchmarks (`stereosplat bench ...`), one module each named as its subcommand, each
//! printing JSON on stdout; and what several share: a held-out drive ([`heldout_drive`]) and
//! resident memory traced over a run ([`rss_trace`]).

pub mod check;
pub mod drive;
pub mod export;
pub mod fusion;
pub mod heldout_drive;
pub mod inputs;
pub mod keep_up;
pub mod model;
pub mod node;
pub mod pareto;
pub mod render;
pub mod rss_trace;
pub mod view;
pub mod workers;
