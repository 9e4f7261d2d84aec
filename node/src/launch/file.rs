//! The launch file's TOML schema, exactly as written (before vars are substituted and
//! references checked, which [`super::plan`] does).
//!
//! ```toml
//! grace_period_s = 5.0                      # Ctrl-C or a failure: SIGINT/SIGTERM, then SIGKILL after this
//! zenoh_config = "${launch_dir}/zenoh.json5" # optional; every process gets STEREOSPLAT_ZENOH_CONFIG
//!
//! [vars]                                    # ${name} in the strings below; `--set name=value` overrides
//! out = "out/demo"
//!
//! [[process]]
//! name = "data"
//! subcommand = "research synth-heldout"     # a `stereosplat` subcommand, or `program = "sh"`
//! args = ["--out", "${out}"]
//! oneshot = true                            # expected to exit 0 (default false: runs until stopped)
//!
//! [[process]]
//! name = "eval"
//! subcommand = "research eval"
//! args = ["--data", "${out}"]
//! env = { RUST_LOG = "info" }
//! cwd = "."                                 # relative to the launcher's working directory
//! required = true                           # default true: if it fails (or, when not oneshot, exits), stop everything
//! delay_s = 0.5                             # wait this long once the `after` conditions hold
//! after = [{ process = "data" }]            # `data` exited with status 0; or { process = "x", line = "regex" }
//! stop_after = ["data"]                     # on a stop, signalled only once these have exited
//! ```
//!
//! Unknown keys are rejected (serde's `deny_unknown_fields`), so a misspelt key is an error
//! naming the key and its line instead of a silently ignored setting.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use super::error::{LaunchError, Place};

/// The top level of a launch file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaunchFile {
    /// Named values substituted as `${name}` into the processes' strings (strings, numbers
    /// or booleans; all become text).
    #[serde(default)]
    pub vars: BTreeMap<String, Spanned<toml::Value>>,
    /// The zenoh session config every process shares (exported as
    /// `STEREOSPLAT_ZENOH_CONFIG` and available as `${zenoh_config}`).
    pub zenoh_config: Option<Spanned<String>>,
    /// Seconds between asking the processes to stop and killing them.
    pub grace_period_s: Option<Spanned<f64>>,
    /// The processes, in start order (the `after` conditions aside).
    #[serde(default, rename = "process")]
    pub processes: Vec<ProcessEntry>,
}

/// One `[[process]]` table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProcessEntry {
    /// Unique name, used in the `[name] ` prefix of its output and in `after`.
    pub name: Spanned<String>,
    /// A `stereosplat` subcommand (run with the launcher's own executable), its words
    /// separated by spaces where it is in a group (`research synth-heldout`, `bench node`).
    pub subcommand: Option<Spanned<String>>,
    /// Any other program (looked up on `PATH`); exactly one of this and `subcommand`.
    pub program: Option<Spanned<String>>,
    /// Arguments after the subcommand or program.
    #[serde(default)]
    pub args: Vec<Spanned<String>>,
    /// Extra environment variables (the launcher's own are inherited).
    #[serde(default)]
    pub env: BTreeMap<String, Spanned<String>>,
    /// Working directory (default: the launcher's).
    pub cwd: Option<Spanned<String>>,
    /// Conditions that must all hold before the process starts.
    #[serde(default)]
    pub after: Vec<Dependency>,
    /// Seconds to wait after the `after` conditions hold (or after launch, without any).
    pub delay_s: Option<Spanned<f64>>,
    /// When the launch stops, this process is signalled only once these have exited (a
    /// worker or a router outlives the node it serves while the node finishes its bins);
    /// the grace period still ends in SIGKILL for all.
    #[serde(default)]
    pub stop_after: Vec<Spanned<String>>,
    /// Whether its failure stops the whole launch (default true).
    pub required: Option<bool>,
    /// Whether it is expected to finish with status 0 (default false: it runs until stopped).
    #[serde(default)]
    pub oneshot: bool,
}

/// One `after` condition.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Dependency {
    /// The process waited for.
    pub process: Spanned<String>,
    /// A regular expression: wait until `process` prints a matching line (stdout or
    /// stderr). Without it, wait until `process` exits with status 0.
    pub line: Option<Spanned<String>>,
}

impl LaunchFile {
    /// Parses `text`, the contents of `path` (used only in error messages).
    pub fn parse(text: &str, path: &Path) -> Result<LaunchFile, LaunchError> {
        toml::from_str(text).map_err(|e| LaunchError::Syntax {
            place: Place::at(path.to_path_buf(), text, e.span().map(|s| s.start)),
            message: e.message().trim().to_string(),
        })
    }
}
