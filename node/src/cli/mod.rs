//! The commands that operate the node and its maps, one module each named as its subcommand,
//! and the flag helpers they share ([`common`]). Research commands are in
//! [`crate::research`], benchmarks in [`crate::bench`].

pub mod common;
pub mod demo;
pub mod export;
pub mod launch;
pub mod monitor;
pub mod reconstruct;
pub mod record;
pub mod render;
pub mod replay;
pub mod router;
pub mod run;
pub mod view;
pub mod worker;
