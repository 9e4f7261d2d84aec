//! `stereosplat launch FILE [--set key=value ...]`: run a graph of processes from a launch
//! file (see [`crate::launch`]); the exit status is 0 when every process ended well, the
//! failed process's status otherwise, 130 after Ctrl-C.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, ValueEnum};

use crate::launch::{self, parse_override, Ending, Options, Plan};

/// When to colour the `[name] ` prefixes.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum ColorChoice {
    /// When stdout is a terminal and `NO_COLOR` is not set.
    Auto,
    /// Always.
    Always,
    /// Never.
    Never,
}

/// Flags of `launch`.
#[derive(Args, Clone, Debug)]
pub struct LaunchArgs {
    /// The launch file (TOML; see `launch/*.toml`).
    file: PathBuf,
    /// Override a var of the file's `[vars]` (repeatable), e.g. `--set frames=20`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Colour the `[name] ` prefixes.
    #[arg(long, value_enum, default_value_t = ColorChoice::Auto)]
    color: ColorChoice,
    /// Check the file and print what would run, without starting anything.
    #[arg(long)]
    check: bool,
}

/// Runs the launch; exits the process with the launch's status when it did not succeed.
pub fn run(args: &LaunchArgs) -> Result<()> {
    let overrides = args
        .set
        .iter()
        .map(|s| parse_override(s))
        .collect::<Result<Vec<_>, _>>()?;
    let exe = std::env::current_exe().map_err(launch::LaunchError::CurrentExe)?;
    let plan = Plan::load(&args.file, &overrides, &exe)?;
    if args.check {
        println!("{plan}");
        return Ok(());
    }
    let color = match args.color {
        ColorChoice::Always => true,
        ColorChoice::Never => false,
        ColorChoice::Auto => {
            std::io::stdout().is_terminal() && std::env::var_os("NO_COLOR").is_none()
        }
    };
    match launch::run(&plan, &Options { color })? {
        Ending::Success => Ok(()),
        ending => {
            eprintln!("launch: {ending}");
            std::process::exit(ending.exit_code());
        }
    }
}
