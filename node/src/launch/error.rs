//! The launcher's typed errors: every problem with a launch file names the file and, where
//! the TOML parser gives one, the line.

use std::fmt;
use std::path::PathBuf;

/// Where in a launch file a problem is: the file, and the 1-based line and column when known.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Place {
    /// The launch file.
    pub path: PathBuf,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// 1-based column, when known.
    pub column: Option<usize>,
}

impl Place {
    /// The place of byte offset `offset` of `text` (the file's contents) in `path`.
    pub fn at(path: PathBuf, text: &str, offset: Option<usize>) -> Place {
        let (line, column) = match offset {
            Some(offset) => {
                let before = &text[..floor_char_boundary(text, offset)];
                let line = before.matches('\n').count() + 1;
                let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
                (Some(line), Some(column))
            }
            None => (None, None),
        };
        Place { path, line, column }
    }
}

fn floor_char_boundary(text: &str, offset: usize) -> usize {
    let mut i = offset.min(text.len());
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(column) = self.column {
                write!(f, ":{column}")?;
            }
        }
        Ok(())
    }
}

/// Everything that keeps a launch from starting (a process failing at run time is not an
/// error but the launch's outcome, see [`super::Ending`]).
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// The launch file could not be read (missing, unreadable).
    #[error("cannot read launch file {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not valid TOML or does not fit the schema (unknown key, wrong type, ...).
    #[error("{place}: {message}")]
    Syntax {
        /// Where.
        place: Place,
        /// The parser's message (it names an unknown key and the keys allowed there).
        message: String,
    },
    /// The file parses but describes an impossible launch (cycle, unknown process, ...).
    #[error("{place}: {message}")]
    Invalid {
        /// Where.
        place: Place,
        /// What is wrong.
        message: String,
    },
    /// A `--set` argument is not `key=value` or names a var the file does not have.
    #[error("--set {given}: {message}")]
    Override {
        /// The argument as given.
        given: String,
        /// What is wrong.
        message: String,
    },
    /// The path of the running `stereosplat` executable (which runs subcommands) is unknown.
    #[error("cannot find the stereosplat executable to run subcommands: {0}")]
    CurrentExe(std::io::Error),
    /// Signal handlers for Ctrl-C could not be installed.
    #[error("cannot install the SIGINT/SIGTERM handlers: {0}")]
    Signals(std::io::Error),
}
