//! A checked launch: vars substituted, references resolved to indices, no cycles. What the
//! supervisor runs, and what `stereosplat launch --check` prints.

use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Duration;

use regex::Regex;
use toml::Spanned;

use super::error::{LaunchError, Place};
use super::file::{Dependency, LaunchFile, ProcessEntry};
use super::vars::{substitute, SubstituteError};

/// Grace period when the file sets none: seconds between asking processes to stop and
/// killing them.
pub const DEFAULT_GRACE_PERIOD_S: f64 = 5.0;

/// The environment variable that carries the file's `zenoh_config` to every process.
pub const ZENOH_CONFIG_ENV: &str = "STEREOSPLAT_ZENOH_CONFIG";

/// Vars every launch file has without defining them.
const BUILTIN_VARS: [&str; 2] = ["launch_dir", "zenoh_config"];

/// A launch ready to run.
#[derive(Debug)]
pub struct Plan {
    /// The processes, in the file's order.
    pub processes: Vec<ProcessSpec>,
    /// Time between the stop signal and SIGKILL.
    pub grace_period: Duration,
}

/// One process, fully resolved.
#[derive(Debug)]
pub struct ProcessSpec {
    /// Its unique name.
    pub name: String,
    /// The executable (the `stereosplat` binary for a subcommand).
    pub program: PathBuf,
    /// Every argument, the subcommand first where there is one.
    pub args: Vec<String>,
    /// Environment variables added to the launcher's.
    pub env: Vec<(String, String)>,
    /// Working directory, when not the launcher's.
    pub cwd: Option<PathBuf>,
    /// Conditions that must all hold before it starts.
    pub after: Vec<Wait>,
    /// Time to wait once they hold.
    pub delay: Duration,
    /// Indices of the processes that must have exited before this one is signalled to
    /// stop.
    pub stop_after: Vec<usize>,
    /// Whether its failure stops the launch.
    pub required: bool,
    /// Whether it is expected to exit (with status 0) rather than run until stopped.
    pub oneshot: bool,
}

/// A start condition on another process.
#[derive(Debug)]
pub struct Wait {
    /// Index of the process waited for in [`Plan::processes`].
    pub process: usize,
    /// What it must do.
    pub until: Until,
}

/// What the awaited process must do.
#[derive(Debug)]
pub enum Until {
    /// Print a line (stdout or stderr) matching this expression.
    Line(Regex),
    /// Exit with status 0.
    Success,
}

impl Plan {
    /// Reads and checks the launch file at `path`. `overrides` are `--set` pairs (each must
    /// name a var of the file); `stereosplat` is the executable that runs subcommands.
    pub fn load(
        path: &Path,
        overrides: &[(String, String)],
        stereosplat: &Path,
    ) -> Result<Plan, LaunchError> {
        let text = std::fs::read_to_string(path).map_err(|source| LaunchError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Plan::parse(&text, path, overrides, stereosplat)
    }

    /// Checks `text`, the contents of the launch file `path` (see [`Plan::load`]).
    pub fn parse(
        text: &str,
        path: &Path,
        overrides: &[(String, String)],
        stereosplat: &Path,
    ) -> Result<Plan, LaunchError> {
        let file = LaunchFile::parse(text, path)?;
        let checker = Checker { text, path };
        let vars = checker.vars(&file, overrides)?;
        let names = checker.names(&file.processes)?;
        let processes = file
            .processes
            .iter()
            .map(|entry| checker.process(entry, &names, &vars, stereosplat))
            .collect::<Result<Vec<_>, _>>()?;
        checker.no_cycle(&file.processes, &processes)?;
        let grace = match &file.grace_period_s {
            Some(g) => checker.seconds(g, "grace_period_s")?,
            None => Duration::from_secs_f64(DEFAULT_GRACE_PERIOD_S),
        };
        Ok(Plan {
            processes,
            grace_period: grace,
        })
    }
}

/// Parses a `--set key=value` argument.
pub fn parse_override(given: &str) -> Result<(String, String), LaunchError> {
    match given.split_once('=') {
        Some((key, value)) if !key.trim().is_empty() => {
            Ok((key.trim().to_string(), value.to_string()))
        }
        _ => Err(LaunchError::Override {
            given: given.to_string(),
            message: "expected key=value".into(),
        }),
    }
}

/// Turns file-level facts into errors that point into the file.
struct Checker<'a> {
    text: &'a str,
    path: &'a Path,
}

impl Checker<'_> {
    fn invalid(&self, span: Range<usize>, message: String) -> LaunchError {
        LaunchError::Invalid {
            place: Place::at(self.path.to_path_buf(), self.text, Some(span.start)),
            message,
        }
    }

    /// The vars: the file's, overridden by `--set`, plus the built-in ones.
    fn vars(
        &self,
        file: &LaunchFile,
        overrides: &[(String, String)],
    ) -> Result<BTreeMap<String, String>, LaunchError> {
        let mut vars = BTreeMap::new();
        for (name, value) in &file.vars {
            if BUILTIN_VARS.contains(&name.as_str()) {
                let message = format!("var `{name}` is built in and cannot be redefined");
                return Err(self.invalid(value.span(), message));
            }
            let text = match value.get_ref() {
                toml::Value::String(s) => s.clone(),
                toml::Value::Integer(i) => i.to_string(),
                toml::Value::Float(f) => f.to_string(),
                toml::Value::Boolean(b) => b.to_string(),
                _ => {
                    let message = format!("var `{name}` must be a string, number or boolean");
                    return Err(self.invalid(value.span(), message));
                }
            };
            vars.insert(name.clone(), text);
        }
        for (key, value) in overrides {
            match vars.get_mut(key) {
                Some(slot) => *slot = value.clone(),
                None => {
                    let known = file.vars.keys().cloned().collect::<Vec<_>>().join(", ");
                    return Err(LaunchError::Override {
                        given: format!("{key}={value}"),
                        message: format!(
                            "{} has no var `{key}` (its vars: {})",
                            self.path.display(),
                            if known.is_empty() { "none" } else { &known }
                        ),
                    });
                }
            }
        }
        let dir = self.path.parent().unwrap_or(Path::new("."));
        let dir = std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf());
        vars.insert("launch_dir".into(), dir.display().to_string());
        if let Some(zenoh) = &file.zenoh_config {
            let value = self.substitute(zenoh, &vars)?;
            vars.insert("zenoh_config".into(), value);
        }
        Ok(vars)
    }

    fn substitute(
        &self,
        text: &Spanned<String>,
        vars: &BTreeMap<String, String>,
    ) -> Result<String, LaunchError> {
        substitute(text.get_ref(), vars).map_err(|e| {
            let message = match e {
                SubstituteError::Unknown(name) => {
                    let known = vars.keys().cloned().collect::<Vec<_>>().join(", ");
                    format!("unknown var `${{{name}}}` (vars: {known})")
                }
                SubstituteError::Unclosed => {
                    format!("`${{` without a closing `}}` in {:?}", text.get_ref())
                }
            };
            self.invalid(text.span(), message)
        })
    }

    /// Name to index, rejecting empty and duplicate names.
    fn names(&self, processes: &[ProcessEntry]) -> Result<BTreeMap<String, usize>, LaunchError> {
        let mut names = BTreeMap::new();
        for (i, entry) in processes.iter().enumerate() {
            let name = entry.name.get_ref();
            if name.is_empty() || name.chars().any(char::is_whitespace) {
                let message = format!("process name {name:?} must be non-empty, without spaces");
                return Err(self.invalid(entry.name.span(), message));
            }
            if names.insert(name.clone(), i).is_some() {
                let message = format!("two processes are named `{name}`");
                return Err(self.invalid(entry.name.span(), message));
            }
        }
        Ok(names)
    }

    fn process(
        &self,
        entry: &ProcessEntry,
        names: &BTreeMap<String, usize>,
        vars: &BTreeMap<String, String>,
        stereosplat: &Path,
    ) -> Result<ProcessSpec, LaunchError> {
        let name = entry.name.get_ref().clone();
        let mut args = Vec::with_capacity(entry.args.len() + 1);
        let program = match (&entry.subcommand, &entry.program) {
            (Some(sub), None) => {
                // A grouped subcommand is its words: `research synth-heldout` is two.
                let sub = self.substitute(sub, vars)?;
                if sub.split_whitespace().next().is_none() {
                    let message = format!("process `{name}` has an empty `subcommand`");
                    return Err(self.invalid(entry.name.span(), message));
                }
                args.extend(sub.split_whitespace().map(str::to_string));
                stereosplat.to_path_buf()
            }
            (None, Some(program)) => PathBuf::from(self.substitute(program, vars)?),
            _ => {
                let message =
                    format!("process `{name}` needs exactly one of `subcommand` and `program`");
                return Err(self.invalid(entry.name.span(), message));
            }
        };
        for arg in &entry.args {
            args.push(self.substitute(arg, vars)?);
        }
        let mut env = Vec::with_capacity(entry.env.len() + 1);
        if let Some(zenoh) = vars.get("zenoh_config") {
            env.push((ZENOH_CONFIG_ENV.to_string(), zenoh.clone()));
        }
        for (key, value) in &entry.env {
            env.push((key.clone(), self.substitute(value, vars)?));
        }
        let cwd = match &entry.cwd {
            Some(cwd) => Some(PathBuf::from(self.substitute(cwd, vars)?)),
            None => None,
        };
        let after = entry
            .after
            .iter()
            .map(|dep| self.wait(dep, names, &name))
            .collect::<Result<Vec<_>, _>>()?;
        let delay = match &entry.delay_s {
            Some(d) => self.seconds(d, "delay_s")?,
            None => Duration::ZERO,
        };
        let stop_after = entry
            .stop_after
            .iter()
            .map(|other| match names.get(other.get_ref()) {
                Some(&i) => Ok(i),
                None => {
                    let message = format!(
                        "process `{name}` stops after `{}`, which is not a process here",
                        other.get_ref()
                    );
                    Err(self.invalid(other.span(), message))
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(ProcessSpec {
            name,
            program,
            args,
            env,
            cwd,
            after,
            delay,
            stop_after,
            required: entry.required.unwrap_or(true),
            oneshot: entry.oneshot,
        })
    }

    fn wait(
        &self,
        dep: &Dependency,
        names: &BTreeMap<String, usize>,
        waiter: &str,
    ) -> Result<Wait, LaunchError> {
        let target = dep.process.get_ref();
        let Some(&process) = names.get(target) else {
            let known = names.keys().cloned().collect::<Vec<_>>().join(", ");
            let message = format!(
                "process `{waiter}` waits for `{target}`, which is not a process here \
                 (processes: {known})"
            );
            return Err(self.invalid(dep.process.span(), message));
        };
        let until =
            match &dep.line {
                Some(pattern) => Until::Line(Regex::new(pattern.get_ref()).map_err(|e| {
                    self.invalid(pattern.span(), format!("bad `line` pattern: {e}"))
                })?),
                None => Until::Success,
            };
        Ok(Wait { process, until })
    }

    fn seconds(&self, value: &Spanned<f64>, key: &str) -> Result<Duration, LaunchError> {
        Duration::try_from_secs_f64(*value.get_ref()).map_err(|_| {
            let message = format!("`{key}` must be a non-negative number of seconds");
            self.invalid(value.span(), message)
        })
    }

    /// Rejects a cycle in `after` (which would keep its processes waiting for ever).
    fn no_cycle(
        &self,
        entries: &[ProcessEntry],
        processes: &[ProcessSpec],
    ) -> Result<(), LaunchError> {
        // Depth-first search; `path` is the chain being explored, `done` the cleared nodes.
        let mut done = vec![false; processes.len()];
        for start in 0..processes.len() {
            let mut path = Vec::new();
            if let Some(cycle) = find_cycle(processes, start, &mut path, &mut done) {
                let chain = cycle
                    .iter()
                    .map(|&i| processes[i].name.as_str())
                    .collect::<Vec<_>>()
                    .join(" -> ");
                let message = format!("cycle in `after`: {chain}");
                return Err(self.invalid(entries[cycle[0]].name.span(), message));
            }
        }
        Ok(())
    }
}

/// The cycle reachable from `node` as a closed chain (first == last), if there is one.
fn find_cycle(
    processes: &[ProcessSpec],
    node: usize,
    path: &mut Vec<usize>,
    done: &mut [bool],
) -> Option<Vec<usize>> {
    if done[node] {
        return None;
    }
    if let Some(at) = path.iter().position(|&p| p == node) {
        let mut cycle = path[at..].to_vec();
        cycle.push(node);
        return Some(cycle);
    }
    path.push(node);
    for wait in &processes[node].after {
        if let Some(cycle) = find_cycle(processes, wait.process, path, done) {
            return Some(cycle);
        }
    }
    path.pop();
    done[node] = true;
    None
}

impl fmt::Display for Plan {
    /// One line per process: its command line and what it waits for.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for p in &self.processes {
            let kind = match (p.oneshot, p.required) {
                (true, true) => "oneshot",
                (true, false) => "oneshot, optional",
                (false, true) => "required",
                (false, false) => "optional",
            };
            write!(f, "{} ({kind}): {}", p.name, p.program.display())?;
            for arg in &p.args {
                write!(f, " {arg}")?;
            }
            for wait in &p.after {
                let other = &self.processes[wait.process].name;
                match &wait.until {
                    Until::Line(re) => write!(f, "; after {other} prints /{re}/")?,
                    Until::Success => write!(f, "; after {other} succeeds")?,
                }
            }
            if !p.delay.is_zero() {
                write!(f, "; delay {:?}", p.delay)?;
            }
            writeln!(f)?;
        }
        write!(f, "grace period {:?}", self.grace_period)
    }
}
