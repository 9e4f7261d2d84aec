//! Signals in (Ctrl-C / SIGTERM to the launcher) and out (stop a child's process group).
//!
//! Unix first: each child runs in its own process group, so a stop signal reaches the whole
//! group (a `sh -c` script and what it started), and a Ctrl-C in the terminal reaches only the
//! launcher, which then stops the children in an orderly way. Elsewhere the launcher still
//! starts processes and forwards their output, but cannot catch Ctrl-C or stop children.
//!
//! Limits: a child counts as running until it has exited and its output pipes closed, so a
//! grandchild still writing to them is stopped with the group; one that left the group, or
//! outlived its parent with its output sent elsewhere, is not tracked. A launcher killed
//! with SIGKILL cannot stop anything.

use std::io;
use std::thread::JoinHandle;

/// A signal that asks processes to stop, from polite to final.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// SIGINT (what Ctrl-C sends).
    Interrupt,
    /// SIGTERM (what a supervisor or `kill` sends).
    Terminate,
    /// SIGKILL, after the grace period.
    Kill,
}

impl Stop {
    /// The conventional exit status of a program ended by this signal (128 + number).
    pub fn exit_code(self) -> i32 {
        128 + match self {
            Stop::Interrupt => 2,
            Stop::Terminate => 15,
            Stop::Kill => 9,
        }
    }

    /// The signal's name, e.g. `SIGINT`.
    pub fn name(self) -> &'static str {
        match self {
            Stop::Interrupt => "SIGINT",
            Stop::Terminate => "SIGTERM",
            Stop::Kill => "SIGKILL",
        }
    }
}

/// Calls a function for every SIGINT and SIGTERM the launcher gets, until dropped.
pub struct Listener {
    #[cfg(unix)]
    handle: signal_hook::iterator::Handle,
    thread: Option<JoinHandle<()>>,
}

/// Installs the handlers (replacing the default "die at once") and starts the listening
/// thread.
#[cfg(unix)]
pub fn listen(on_signal: impl Fn(Stop) + Send + 'static) -> io::Result<Listener> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM])?;
    let handle = signals.handle();
    let thread = std::thread::spawn(move || {
        for signal in signals.forever() {
            on_signal(match signal {
                SIGINT => Stop::Interrupt,
                _ => Stop::Terminate,
            });
        }
    });
    Ok(Listener {
        handle,
        thread: Some(thread),
    })
}

/// Without unix signals there is nothing to listen to.
#[cfg(not(unix))]
pub fn listen(_on_signal: impl Fn(Stop) + Send + 'static) -> io::Result<Listener> {
    Ok(Listener { thread: None })
}

impl Drop for Listener {
    fn drop(&mut self) {
        #[cfg(unix)]
        self.handle.close();
        if let Some(thread) = self.thread.take() {
            // The thread only forwards signals; if it panicked there is nothing to recover.
            let _ = thread.join();
        }
    }
}

/// Sends `stop` to the process group led by the child `pid` (see the module note).
#[cfg(unix)]
pub fn send(pid: u32, stop: Stop) -> io::Result<()> {
    use nix::sys::signal::{killpg, Signal};
    use nix::unistd::Pid;
    let signal = match stop {
        Stop::Interrupt => Signal::SIGINT,
        Stop::Terminate => Signal::SIGTERM,
        Stop::Kill => Signal::SIGKILL,
    };
    let group = i32::try_from(pid).map_err(|_| io::Error::other("pid out of range"))?;
    killpg(Pid::from_raw(group), signal).map_err(io::Error::from)
}

/// Stopping children needs unix process groups.
#[cfg(not(unix))]
pub fn send(_pid: u32, _stop: Stop) -> io::Result<()> {
    Err(io::Error::new(
        io::ErrorKind::Unsupported,
        "stopping processes needs unix",
    ))
}

/// Puts the child about to be spawned in a process group of its own.
pub fn own_process_group(command: &mut std::process::Command) {
    #[cfg(unix)]
    std::os::unix::process::CommandExt::process_group(command, 0);
    #[cfg(not(unix))]
    let _ = command;
}
