//! Launch files: start a graph of processes (`stereosplat` subcommands or any program) from
//! one TOML file, forward their output behind `[name] ` prefixes, and stop them together.
//!
//! [`mod@file`] is the schema as written, [`plan`] checks it into a [`Plan`] (vars substituted,
//! references and cycles checked), [`supervisor`] runs a plan. Unix first: stopping uses
//! process groups and signals (see [`signals`]).

pub mod error;
pub mod file;
pub mod output;
pub mod plan;
pub mod signals;
pub mod supervisor;
pub mod vars;

pub use error::{LaunchError, Place};
pub use plan::{parse_override, Plan, ProcessSpec, Until, Wait};
pub use signals::Stop;
pub use supervisor::{run, Ending, Options};
