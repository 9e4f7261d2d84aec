//! Running a [`Plan`]: start processes when their `after` conditions hold, forward their
//! output, and stop them all on Ctrl-C, on SIGTERM, or when a required process ends.
//!
//! One thread per child stream reads lines; one thread per child waits for its exit (after
//! its output is drained, so a line always arrives before its process's exit). Everything
//! arrives on one channel that the supervisor loop alone handles: no shared state.

use std::fmt;
use std::io::{BufRead, BufReader, Read};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

use super::error::LaunchError;
use super::output::{Printer, Stream};
use super::plan::{Plan, Until};
use super::signals::{self, Stop};

/// How a launch ended; [`Ending::exit_code`] is the launcher's exit status.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Ending {
    /// Every process exited successfully, or a required long-running process exited with
    /// status 0 and the others were stopped.
    Success,
    /// A process failed (or could not start); the first failure is the one reported.
    Failed {
        /// Its name.
        process: String,
        /// What happened, e.g. `exit status: 3`.
        reason: String,
        /// Its exit code (128 + signal when a signal ended it), which the launcher returns.
        code: i32,
    },
    /// The launcher was told to stop (Ctrl-C or SIGTERM) and stopped everything.
    Interrupted(Stop),
}

impl Ending {
    /// The launcher's exit status: 0, the failed process's code, or 128 + the signal.
    pub fn exit_code(&self) -> i32 {
        match self {
            Ending::Success => 0,
            Ending::Failed { code, .. } => *code,
            Ending::Interrupted(stop) => stop.exit_code(),
        }
    }
}

impl fmt::Display for Ending {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Ending::Success => write!(f, "every process ended successfully"),
            Ending::Failed {
                process, reason, ..
            } => write!(f, "process `{process}` failed: {reason}"),
            Ending::Interrupted(stop) => {
                write!(f, "stopped by {}; every process was stopped", stop.name())
            }
        }
    }
}

/// Settings of a run that are not part of the launch file.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// Colour the `[name] ` prefixes.
    pub color: bool,
}

/// Runs `plan` to the end and says how it ended. Errors only when the launcher itself
/// cannot work (signal handlers); processes that fail are the [`Ending`].
pub fn run(plan: &Plan, options: &Options) -> Result<Ending, LaunchError> {
    let (tx, rx) = channel();
    let signal_tx = tx.clone();
    let _listener = signals::listen(move |stop| {
        let _ = signal_tx.send(Event::Signal(stop));
    })
    .map_err(LaunchError::Signals)?;
    let mut supervisor = Supervisor {
        plan,
        printer: Printer {
            color: options.color,
        },
        states: plan.processes.iter().map(|_| State::Waiting).collect(),
        met: plan
            .processes
            .iter()
            .map(|p| vec![false; p.after.len()])
            .collect(),
        launched: Instant::now(),
        tx,
        kill_at: None,
        stop: None,
        signalled: vec![false; plan.processes.len()],
        killed: false,
        ending: None,
        later_failure: None,
    };
    loop {
        let now = Instant::now();
        supervisor.advance(now);
        if supervisor.states.iter().all(State::is_over) {
            break;
        }
        if supervisor.kill_at.is_some_and(|at| now >= at) && !supervisor.killed {
            supervisor.kill_all("the grace period is over");
        }
        let wake = supervisor
            .next_wake(now)
            .unwrap_or(now + Duration::from_secs(3600));
        match rx.recv_timeout(wake.saturating_duration_since(now)) {
            Ok(event) => supervisor.handle(event),
            Err(RecvTimeoutError::Timeout) => {}
            // The supervisor holds a sender, so the channel never disconnects.
            Err(RecvTimeoutError::Disconnected) => break,
        }
    }
    Ok(supervisor.finish())
}

/// What the threads report to the supervisor loop.
enum Event {
    Line {
        process: usize,
        stream: Stream,
        text: String,
    },
    Exited {
        process: usize,
        status: std::io::Result<ExitStatus>,
    },
    Signal(Stop),
}

/// Where a process is in its life.
#[derive(Debug)]
enum State {
    /// Not started; `Ready` once its conditions hold.
    Waiting,
    /// Its conditions hold; it starts at this instant (after its delay).
    Ready(Instant),
    /// Started, with this pid (also its process group id).
    Running(u32),
    /// Exited, could not start, or could not be waited for.
    Exited,
    /// Never started: the launch stopped first or its conditions can no longer hold.
    Skipped,
}

impl State {
    fn is_over(&self) -> bool {
        matches!(self, State::Exited | State::Skipped)
    }
}

struct Supervisor<'a> {
    plan: &'a Plan,
    printer: Printer,
    states: Vec<State>,
    /// `met[i][k]`: condition `k` of process `i` holds.
    met: Vec<Vec<bool>>,
    launched: Instant,
    tx: Sender<Event>,
    /// When stopping: the instant after which the processes left are killed.
    kill_at: Option<Instant>,
    /// When stopping: the signal sent, and which processes have had it.
    stop: Option<Stop>,
    signalled: Vec<bool>,
    killed: bool,
    /// What started the stop (the first required failure, a signal, a required exit).
    ending: Option<Ending>,
    /// The first failure of a process whose failure does not stop the launch.
    later_failure: Option<Ending>,
}

impl Supervisor<'_> {
    /// Starts what is due, skips what can no longer start; repeats while anything changes.
    fn advance(&mut self, now: Instant) {
        let mut changed = true;
        while changed {
            changed = false;
            for i in 0..self.states.len() {
                changed |= self.advance_one(i, now);
            }
        }
    }

    fn advance_one(&mut self, i: usize, now: Instant) -> bool {
        let spec = &self.plan.processes[i];
        match self.states[i] {
            State::Waiting if self.kill_at.is_some() => self.skip(i, None),
            State::Ready(_) if self.kill_at.is_some() => self.skip(i, None),
            State::Waiting => {
                if let Some(k) = (0..spec.after.len()).find(|&k| self.cannot_hold(i, k)) {
                    let wait = &spec.after[k];
                    let other = &self.plan.processes[wait.process].name;
                    let reason = match &wait.until {
                        Until::Line(re) => format!("`{other}` ended without printing /{re}/"),
                        Until::Success => format!("`{other}` did not exit successfully"),
                    };
                    return self.skip(i, Some(reason));
                }
                if self.met[i].iter().all(|&m| m) {
                    // Without conditions the delay counts from the launch.
                    let from = if spec.after.is_empty() {
                        self.launched
                    } else {
                        now
                    };
                    self.states[i] = State::Ready(from + spec.delay);
                    return true;
                }
                false
            }
            State::Ready(at) if at <= now => {
                self.start(i);
                true
            }
            _ => false,
        }
    }

    /// Whether condition `k` of process `i` is unmet and its process is over.
    fn cannot_hold(&self, i: usize, k: usize) -> bool {
        !self.met[i][k] && self.states[self.plan.processes[i].after[k].process].is_over()
    }

    /// Marks `i` as never started; with a reason, that counts as its failure.
    fn skip(&mut self, i: usize, reason: Option<String>) -> bool {
        self.states[i] = State::Skipped;
        if let Some(reason) = reason {
            self.printer.note(&format!(
                "{} will not start: {reason}",
                self.plan.processes[i].name
            ));
            self.fail(i, format!("not started: {reason}"), 1);
        }
        true
    }

    fn start(&mut self, i: usize) {
        let spec = &self.plan.processes[i];
        let mut command = Command::new(&spec.program);
        command
            .args(&spec.args)
            .envs(spec.env.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        if let Some(cwd) = &spec.cwd {
            command.current_dir(cwd);
        }
        signals::own_process_group(&mut command);
        let mut child = match command.spawn() {
            Ok(child) => child,
            Err(e) => {
                let reason = format!("cannot start {}: {e}", spec.program.display());
                self.printer.note(&format!("{}: {reason}", spec.name));
                self.states[i] = State::Exited;
                self.fail(i, reason, 127);
                return;
            }
        };
        let pid = child.id();
        self.printer
            .note(&format!("started {} (pid {pid})", spec.name));
        self.states[i] = State::Running(pid);
        let readers = [
            child
                .stdout
                .take()
                .map(|s| self.reader(i, Stream::Stdout, s)),
            child
                .stderr
                .take()
                .map(|s| self.reader(i, Stream::Stderr, s)),
        ];
        let tx = self.tx.clone();
        std::thread::spawn(move || {
            let status = child.wait();
            for reader in readers.into_iter().flatten() {
                let _ = reader.join();
            }
            let _ = tx.send(Event::Exited { process: i, status });
        });
    }

    /// A thread sending each line of `stream` (lossily decoded, line ending removed).
    fn reader(
        &self,
        process: usize,
        stream: Stream,
        source: impl Read + Send + 'static,
    ) -> std::thread::JoinHandle<()> {
        let tx = self.tx.clone();
        std::thread::spawn(move || {
            let mut source = BufReader::new(source);
            let mut buf = Vec::new();
            loop {
                buf.clear();
                match source.read_until(b'\n', &mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(_) => {
                        let text = String::from_utf8_lossy(&buf);
                        let text = text.trim_end_matches(['\n', '\r']).to_string();
                        let event = Event::Line {
                            process,
                            stream,
                            text,
                        };
                        if tx.send(event).is_err() {
                            break;
                        }
                    }
                }
            }
        })
    }

    fn handle(&mut self, event: Event) {
        match event {
            Event::Line {
                process,
                stream,
                text,
            } => {
                let name = &self.plan.processes[process].name;
                self.printer.line(process, name, stream, &text);
                self.mark(process, |until| match until {
                    Until::Line(re) => re.is_match(&text),
                    Until::Success => false,
                });
            }
            Event::Exited { process, status } => self.exited(process, status),
            Event::Signal(stop) => {
                if self.kill_at.is_none() {
                    self.printer.note(&format!("got {}, stopping", stop.name()));
                    self.ending.get_or_insert(Ending::Interrupted(stop));
                    self.stop_all(stop);
                } else if !self.killed {
                    self.kill_all(&format!("got {} again", stop.name()));
                }
            }
        }
    }

    /// Marks the conditions on `process` that `holds` accepts.
    fn mark(&mut self, process: usize, holds: impl Fn(&Until) -> bool) {
        for (i, spec) in self.plan.processes.iter().enumerate() {
            if !matches!(self.states[i], State::Waiting) {
                continue;
            }
            for (k, wait) in spec.after.iter().enumerate() {
                if wait.process == process && holds(&wait.until) {
                    self.met[i][k] = true;
                }
            }
        }
    }

    fn exited(&mut self, i: usize, status: std::io::Result<ExitStatus>) {
        let spec = &self.plan.processes[i];
        let (ok, reason, code) = match &status {
            Ok(s) => (s.success(), s.to_string(), exit_code(s)),
            Err(e) => (false, format!("cannot wait for it: {e}"), 1),
        };
        self.printer
            .note(&format!("{} exited: {reason}", spec.name));
        self.states[i] = State::Exited;
        if ok {
            self.mark(i, |until| matches!(until, Until::Success));
        }
        if self.kill_at.is_some() {
            // Stopping: whatever it returns is the stop's doing; those that outlive it
            // are due now.
            self.signal_due();
            return;
        }
        if !ok {
            self.fail(i, reason, code);
        } else if !spec.oneshot && spec.required {
            self.printer.note(&format!(
                "required process {} ended, stopping the others",
                spec.name
            ));
            self.ending.get_or_insert(Ending::Success);
            self.stop_all(Stop::Terminate);
        }
    }

    /// Records process `i`'s failure; a required one stops the launch.
    fn fail(&mut self, i: usize, reason: String, code: i32) {
        let spec = &self.plan.processes[i];
        let failure = Ending::Failed {
            process: spec.name.clone(),
            reason,
            // A failure must never read as success, whatever the child returned.
            code: if code == 0 { 1 } else { code },
        };
        if spec.required && self.kill_at.is_none() {
            self.ending.get_or_insert(failure);
            self.stop_all(Stop::Terminate);
        } else {
            self.later_failure.get_or_insert(failure);
        }
    }

    /// Sends `stop` to every running process and starts the grace period.
    fn stop_all(&mut self, stop: Stop) {
        if self.kill_at.is_some() {
            return;
        }
        self.kill_at = Some(Instant::now() + self.plan.grace_period);
        self.stop = Some(stop);
        self.signal_due();
    }

    /// Sends the stop signal to every running process not signalled yet whose
    /// `stop_after` processes are all over.
    fn signal_due(&mut self) {
        let Some(stop) = self.stop else {
            return;
        };
        for i in 0..self.states.len() {
            let State::Running(pid) = self.states[i] else {
                continue;
            };
            let spec = &self.plan.processes[i];
            if self.signalled[i] || !spec.stop_after.iter().all(|&k| self.states[k].is_over()) {
                continue;
            }
            self.signalled[i] = true;
            self.send(pid, &spec.name, stop);
        }
    }

    fn kill_all(&mut self, why: &str) {
        self.printer.note(&format!("{why}: killing what is left"));
        self.killed = true;
        self.signal_running(Stop::Kill);
    }

    fn signal_running(&self, stop: Stop) {
        for (i, state) in self.states.iter().enumerate() {
            if let State::Running(pid) = *state {
                self.send(pid, &self.plan.processes[i].name, stop);
            }
        }
    }

    fn send(&self, pid: u32, name: &str, stop: Stop) {
        match signals::send(pid, stop) {
            Ok(()) => self
                .printer
                .note(&format!("sent {} to {name}", stop.name())),
            Err(e) => self
                .printer
                .note(&format!("cannot send {} to {name}: {e}", stop.name())),
        }
    }

    /// The next instant something is due without an event: a start or the kill.
    fn next_wake(&self, now: Instant) -> Option<Instant> {
        let starts = self.states.iter().filter_map(|s| match s {
            State::Ready(at) => Some(*at),
            _ => None,
        });
        let kill = self.kill_at.filter(|_| !self.killed);
        starts.chain(kill).min().map(|at| at.max(now))
    }

    fn finish(self) -> Ending {
        match self.ending {
            Some(Ending::Success) | None => self.later_failure.unwrap_or(Ending::Success),
            Some(ending) => ending,
        }
    }
}

/// The exit code a shell would report: the status code, or 128 + the signal that ended it.
fn exit_code(status: &ExitStatus) -> i32 {
    #[cfg(unix)]
    if let Some(signal) = std::os::unix::process::ExitStatusExt::signal(status) {
        return 128 + signal;
    }
    status.code().unwrap_or(1)
}
