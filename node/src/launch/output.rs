//! Forwarding the children's lines to the launcher's stdout and stderr, each behind a
//! `[name] ` prefix (optionally coloured, one colour per process), plus the launcher's own
//! notes behind `[launch] ` on stderr.

use std::io::Write;

/// Which of a child's output streams a line came from (it goes to the same one of ours).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stream {
    /// Standard output.
    Stdout,
    /// Standard error.
    Stderr,
}

/// ANSI foreground colours cycled through by process index (bold cyan, yellow, ...).
const COLOURS: [&str; 6] = ["36", "33", "35", "32", "34", "31"];

/// Writes prefixed lines; whole lines at a time, so lines of different processes never mix.
#[derive(Debug, Clone, Copy)]
pub struct Printer {
    /// Whether prefixes get ANSI colours.
    pub color: bool,
}

impl Printer {
    /// Writes `text` from process number `index`, named `name`, to the matching stream.
    pub fn line(&self, index: usize, name: &str, stream: Stream, text: &str) {
        let prefix = match self.color {
            true => format!("\x1b[1;{}m[{name}]\x1b[0m", COLOURS[index % COLOURS.len()]),
            false => format!("[{name}]"),
        };
        // A closed stdout or stderr (e.g. `| head`) must not stop the launch: ignore errors.
        let _ = match stream {
            Stream::Stdout => writeln!(std::io::stdout().lock(), "{prefix} {text}"),
            Stream::Stderr => writeln!(std::io::stderr().lock(), "{prefix} {text}"),
        };
    }

    /// Writes one of the launcher's own notes (a process started, exited, was stopped).
    pub fn note(&self, text: &str) {
        let prefix = match self.color {
            true => "\x1b[1m[launch]\x1b[0m",
            false => "[launch]",
        };
        let _ = writeln!(std::io::stderr().lock(), "{prefix} {text}");
    }
}
