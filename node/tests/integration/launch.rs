//! `stereosplat launch`: output forwarding, `after` ordering, failure and Ctrl-C shutdown,
//! bad files, `--set`, and the example launch files. Runs the real binary with `sh -c`
//! processes (unix).

use crate::net_support;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use node::launch::vars::{substitute, SubstituteError};
use node::launch::{LaunchError, Plan};

const EXE: &str = env!("CARGO_BIN_EXE_stereosplat");

/// A fresh empty folder for one test.
fn scratch(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("launch_{test}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn launcher(args: &[&str]) -> Command {
    let mut command = Command::new(EXE);
    command
        .arg("launch")
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    command
}

/// Waits for `child` (a safety net against a hung launcher, not a timing assertion).
fn finish(mut child: Child) -> Output {
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            child.kill().unwrap();
            panic!("the launcher did not end: {:?}", child.wait_with_output());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn launch(args: &[&str]) -> (i32, String, String) {
    let out = finish(launcher(args).spawn().unwrap());
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (
        out.status.code().unwrap_or(-1),
        text(&out.stdout),
        text(&out.stderr),
    )
}

/// Whether `pid` is a live process (a zombie left for an ancestor to reap counts as dead).
fn alive(pid: i32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Err(_) => false,
        Ok(stat) => stat
            .rsplit(") ")
            .next()
            .is_some_and(|s| !s.starts_with('Z')),
    }
}

fn read_pid(path: &Path) -> i32 {
    std::fs::read_to_string(path)
        .unwrap()
        .trim()
        .parse()
        .unwrap()
}

#[test]
fn forwards_each_process_output_with_its_prefix() {
    let dir = scratch("prefixes");
    let file = write(
        &dir,
        "two.toml",
        r#"
[[process]]
name = "alpha"
program = "sh"
args = ["-c", "echo one; echo two"]
oneshot = true

[[process]]
name = "beta"
program = "sh"
args = ["-c", "echo to-stderr >&2; printf 'no newline'"]
oneshot = true
"#,
    );
    let (code, stdout, stderr) = launch(&[file.to_str().unwrap(), "--color", "never"]);
    assert_eq!(code, 0, "{stderr}");
    let lines: Vec<&str> = stdout.lines().collect();
    let alpha: Vec<&str> = lines
        .iter()
        .copied()
        .filter(|l| l.starts_with("[alpha] "))
        .collect();
    assert_eq!(alpha, ["[alpha] one", "[alpha] two"]);
    assert!(lines.contains(&"[beta] no newline"), "{stdout}");
    assert!(stderr.lines().any(|l| l == "[beta] to-stderr"), "{stderr}");
    assert!(!stdout.contains("to-stderr"), "stderr lines stay on stderr");
    assert!(
        stderr.contains("[launch] alpha exited: exit status: 0"),
        "{stderr}"
    );
}

#[test]
fn after_waits_for_a_line_and_for_success() {
    let dir = scratch("after");
    let flag = dir.join("flag");
    let made = dir.join("made");
    let text = format!(
        r#"
[vars]
flag = "{flag}"
made = "{made}"

# Declared first, but may only start once `server` printed "ready".
[[process]]
name = "client"
program = "sh"
args = ["-c", "test -f ${{flag}} && echo saw the flag"]
oneshot = true
after = [{{ process = "server", line = "^rea+dy$" }}]

[[process]]
name = "server"
program = "sh"
args = ["-c", "echo booting; sleep 0.3; touch ${{flag}}; echo ready; sleep 0.3; echo done"]
oneshot = true

[[process]]
name = "maker"
program = "sh"
args = ["-c", "sleep 0.2; echo made > ${{made}}"]
oneshot = true

[[process]]
name = "user"
program = "cat"
args = ["${{made}}"]
oneshot = true
after = [{{ process = "maker" }}]
"#,
        flag = flag.display(),
        made = made.display()
    );
    let file = write(&dir, "after.toml", &text);
    let (code, stdout, stderr) = launch(&[file.to_str().unwrap()]);
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    let at = |needle: &str| {
        stdout
            .find(needle)
            .unwrap_or_else(|| panic!("{needle}: {stdout}"))
    };
    assert!(at("[server] booting") < at("[server] ready"));
    assert!(at("[server] ready") < at("[client] saw the flag"));
    assert!(stdout.contains("[user] made"), "{stdout}");
}

#[test]
fn a_failing_required_process_stops_the_others() {
    let dir = scratch("failure");
    let text = format!(
        r#"
grace_period_s = 0.5

[[process]]
name = "polite"
program = "sh"
args = ["-c", "echo $$ > {dir}/polite.pid; exec sleep 30"]

[[process]]
name = "stubborn"
program = "sh"
args = ["-c", "trap '' TERM; echo $$ > {dir}/stubborn.pid; sleep 30"]

[[process]]
name = "crasher"
program = "sh"
args = ["-c", "sleep 0.3; echo giving up >&2; exit 3"]
"#,
        dir = dir.display()
    );
    let file = write(&dir, "fail.toml", &text);
    let (code, _stdout, stderr) = launch(&[file.to_str().unwrap()]);
    assert_eq!(code, 3, "the failed process's status: {stderr}");
    assert!(
        stderr.contains("launch: process `crasher` failed: exit status: 3"),
        "{stderr}"
    );
    // SIGTERM stops `polite` at once; `stubborn` ignores it and is killed after the grace.
    assert!(stderr.contains("polite exited: signal: 15"), "{stderr}");
    assert!(stderr.contains("stubborn exited: signal: 9"), "{stderr}");
    for name in ["polite", "stubborn"] {
        let pid = read_pid(&dir.join(format!("{name}.pid")));
        assert!(!alive(pid), "{name} (pid {pid}) survived");
    }
}

#[test]
fn sigint_stops_every_child_and_grandchild() {
    let dir = scratch("sigint");
    let text = format!(
        r#"
grace_period_s = 1.0

[[process]]
name = "direct"
program = "sh"
args = ["-c", "echo $$ > {dir}/direct.pid.tmp; mv {dir}/direct.pid.tmp {dir}/direct.pid; exec sleep 30"]

# A background job ignores SIGINT (POSIX), so only the group kill after the grace ends it.
[[process]]
name = "parent"
program = "sh"
args = ["-c", "sleep 30 & echo $! > {dir}/bg.pid.tmp; mv {dir}/bg.pid.tmp {dir}/bg.pid; wait"]
"#,
        dir = dir.display()
    );
    let file = write(&dir, "sigint.toml", &text);
    let child = launcher(&[file.to_str().unwrap()]).spawn().unwrap();
    let pids = ["direct.pid", "bg.pid"].map(|f| dir.join(f));
    let deadline = Instant::now() + Duration::from_secs(20);
    while !pids.iter().all(|p| p.exists()) {
        assert!(Instant::now() < deadline, "the processes did not start");
        std::thread::sleep(Duration::from_millis(20));
    }
    let pids = pids.map(|p| read_pid(&p));
    assert!(pids.iter().all(|&p| alive(p)));
    let launcher_pid = nix::unistd::Pid::from_raw(child.id() as i32);
    nix::sys::signal::kill(launcher_pid, nix::sys::signal::Signal::SIGINT).unwrap();
    let out = finish(child);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("got SIGINT, stopping"), "{stderr}");
    assert!(stderr.contains("launch: stopped by SIGINT"), "{stderr}");
    for pid in pids {
        assert!(!alive(pid), "pid {pid} survived: {stderr}");
    }
}

/// The error `Plan::parse` gives for `text`, as displayed.
fn plan_error(text: &str) -> String {
    let err = Plan::parse(text, Path::new("bad.toml"), &[], Path::new(EXE)).unwrap_err();
    err.to_string()
}

#[test]
fn bad_files_name_the_problem_and_the_line() {
    let unknown_key = "[[process]]\nname = \"a\"\nprogram = \"true\"\nrequierd = true\n";
    let err = plan_error(unknown_key);
    assert!(err.starts_with("bad.toml:4:1: "), "{err}");
    assert!(err.contains("requierd"), "{err}");

    let top_key = "grace = 1\n";
    let err = plan_error(top_key);
    assert!(
        err.starts_with("bad.toml:1:1: ") && err.contains("grace"),
        "{err}"
    );

    let cycle = r#"
[[process]]
name = "a"
program = "true"
after = [{ process = "c" }]

[[process]]
name = "b"
program = "true"
after = [{ process = "a", line = "x" }]

[[process]]
name = "c"
program = "true"
after = [{ process = "b" }]
"#;
    assert_eq!(
        plan_error(cycle),
        "bad.toml:3:8: cycle in `after`: a -> c -> b -> a"
    );

    let unknown_ref =
        "[[process]]\nname = \"a\"\nprogram = \"true\"\nafter = [{ process = \"ghost\" }]\n";
    let err = plan_error(unknown_ref);
    assert!(err.starts_with("bad.toml:4:"), "{err}");
    assert!(
        err.contains("`a` waits for `ghost`, which is not a process here"),
        "{err}"
    );

    let both = "[[process]]\nname = \"a\"\nprogram = \"true\"\nsubcommand = \"eval\"\n";
    assert!(plan_error(both).contains("exactly one of `subcommand` and `program`"));

    let twice = "[[process]]\nname = \"a\"\nprogram = \"true\"\n[[process]]\nname = \"a\"\nprogram = \"true\"\n";
    assert_eq!(
        plan_error(twice),
        "bad.toml:5:8: two processes are named `a`"
    );

    let bad_var = "[[process]]\nname = \"a\"\nprogram = \"echo\"\nargs = [\"${nope}\"]\n";
    assert!(plan_error(bad_var).contains("unknown var `${nope}`"));

    let bad_regex = "[[process]]\nname = \"a\"\nprogram = \"true\"\n[[process]]\nname = \"b\"\nprogram = \"true\"\nafter = [{ process = \"a\", line = \"(\" }]\n";
    assert!(plan_error(bad_regex).starts_with("bad.toml:7:"));

    let negative = "grace_period_s = -1.0\n";
    assert!(plan_error(negative).contains("non-negative"));
}

#[test]
fn the_binary_reports_bad_files_and_exits_non_zero() {
    let dir = scratch("bad_binary");
    let file = write(
        &dir,
        "cycle.toml",
        "[[process]]\nname = \"a\"\nprogram = \"true\"\nafter = [{ process = \"a\" }]\n",
    );
    let (code, _, stderr) = launch(&[file.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(
        stderr.contains("cycle.toml:2:8: cycle in `after`: a -> a"),
        "{stderr}"
    );

    let missing = dir.join("missing.toml");
    let (code, _, stderr) = launch(&[missing.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(stderr.contains("cannot read launch file"), "{stderr}");
    assert!(stderr.contains("missing.toml"), "{stderr}");
    let err = Plan::load(&missing, &[], Path::new(EXE)).unwrap_err();
    assert!(matches!(err, LaunchError::Read { .. }));
}

#[test]
fn set_overrides_a_var_and_rejects_unknown_ones() {
    let dir = scratch("set");
    let file = write(
        &dir,
        "set.toml",
        r#"
[vars]
greeting = "hello"
count = 2

[[process]]
name = "say"
program = "sh"
args = ["-c", "echo ${greeting} x${count} $${HOME:+home-is-set} $$ > /dev/null; echo ${greeting} x${count}"]
oneshot = true
"#,
    );
    let path = file.to_str().unwrap();
    let (code, stdout, stderr) = launch(&[path]);
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.lines().any(|l| l == "[say] hello x2"), "{stdout}");

    let (code, stdout, stderr) = launch(&[path, "--set", "greeting=bye", "--set", "count=7"]);
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.lines().any(|l| l == "[say] bye x7"), "{stdout}");

    let (code, _, stderr) = launch(&[path, "--set", "greting=bye"]);
    assert_ne!(code, 0);
    assert!(
        stderr.contains("--set greting=bye: ")
            && stderr.contains("no var `greting` (its vars: count, greeting)"),
        "{stderr}"
    );
    let (code, _, stderr) = launch(&[path, "--set", "greeting"]);
    assert_ne!(code, 0);
    assert!(
        stderr.contains("--set greeting: expected key=value"),
        "{stderr}"
    );
}

#[test]
fn substitution_escapes_and_errors() {
    let vars = BTreeMap::from([("a".to_string(), "1".to_string())]);
    assert_eq!(
        substitute("x${a}y$${a}$HOME$$", &vars).unwrap(),
        "x1y${a}$HOME$$"
    );
    assert_eq!(
        substitute("${b}", &vars),
        Err(SubstituteError::Unknown("b".into()))
    );
    assert_eq!(substitute("${a", &vars), Err(SubstituteError::Unclosed));
}

#[test]
fn a_dependency_that_can_never_hold_fails_the_launch() {
    let dir = scratch("never");
    let file = write(
        &dir,
        "never.toml",
        r#"
[[process]]
name = "quiet"
program = "true"
oneshot = true

[[process]]
name = "waiter"
program = "echo"
args = ["should not run"]
after = [{ process = "quiet", line = "ready" }]
"#,
    );
    let (code, stdout, stderr) = launch(&[file.to_str().unwrap()]);
    assert_eq!(code, 1, "{stderr}");
    assert!(!stdout.contains("should not run"));
    assert!(
        stderr.contains(
            "process `waiter` failed: not started: `quiet` ended without printing /ready/"
        ),
        "{stderr}"
    );
}

#[test]
fn example_files_check() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for name in ["eval_synthetic.toml", "node_demo.toml", "node_workers.toml"] {
        let file = root.join("launch").join(name);
        let (code, stdout, stderr) = launch(&[file.to_str().unwrap(), "--check"]);
        assert_eq!(code, 0, "{name}: {stderr}");
        assert!(stdout.contains("data (oneshot): "), "{name}: {stdout}");
    }
    let plan = Plan::load(&root.join("launch/node_demo.toml"), &[], Path::new(EXE)).unwrap();
    let names: Vec<&str> = plan.processes.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["data", "node", "record", "monitor", "replay"]);
    let node = &plan.processes[1];
    assert_eq!(node.args[..3], ["run", "--listen", "tcp/127.0.0.1:7447"]);
    // A grouped subcommand is passed as its words.
    let data = &plan.processes[0];
    assert_eq!(data.args[..3], ["research", "synth-heldout", "--out"]);
}

#[test]
fn an_empty_subcommand_is_refused() {
    let empty = "[[process]]\nname = \"a\"\nsubcommand = \"  \"\n";
    assert!(plan_error(empty).contains("process `a` has an empty `subcommand`"));
}

/// The node demo through the launcher, with renders on wgpu (lavapipe here) and a home
/// folder of its own, so the test also sees where Mesa's shader cache goes: inside the
/// node's out folder, never under the home folder.
#[test]
fn the_node_demo_replays_a_drive_into_the_node_and_exports_the_map() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let tmp = std::env::temp_dir().join(format!("stereosplat-demo-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let port = net_support::free_port();
    let record_port = net_support::free_port();
    let set = |k: &str, v: String| ["--set".to_string(), format!("{k}={v}")];
    let mut args = vec![root.join("launch/node_demo.toml").display().to_string()];
    for (k, v) in [
        ("data", tmp.join("data").display().to_string()),
        ("out", tmp.join("out").display().to_string()),
        ("endpoint", format!("tcp/127.0.0.1:{port}")),
        ("record_endpoint", format!("tcp/127.0.0.1:{record_port}")),
        ("frames", "40".into()),
        ("width", "136".into()),
        ("height", "40".into()),
        // At the recorded rate the node, rendering on lavapipe, keeps up even on a loaded
        // machine, so the recorder hears every closed bin's latency before the launch stops.
        ("rate", "1".into()),
        ("renders", "gpu".into()),
    ] {
        args.extend(set(k, v));
    }
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let home = tmp.join("home");
    std::fs::create_dir_all(&home).unwrap();
    let run = finish(
        launcher(&refs)
            .env("HOME", &home)
            .env_remove("XDG_CACHE_HOME")
            .env_remove("MESA_SHADER_CACHE_DIR")
            .env_remove("MESA_SHADER_CACHE_DISABLE")
            .spawn()
            .unwrap(),
    );
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    let (code, stdout, stderr) = (
        run.status.code().unwrap_or(-1),
        text(&run.stdout),
        text(&run.stderr),
    );
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    assert!(stdout.contains("[replay] replayed 40 frames"), "{stdout}");
    assert!(stdout.contains("\"bins_published\":"), "{stdout}");
    for f in ["global_map.ply", "global_map_bev.png", "global_map.ssgmap"] {
        assert!(tmp.join("out").join(f).exists(), "{f}");
    }
    assert!(
        !home.join(".cache").exists(),
        "nothing written under the home folder: {:?}",
        std::fs::read_dir(home.join(".cache")).map(|d| d.count())
    );
    assert!(tmp.join("out/shader_cache").is_dir());
    // The recorder heard the inputs and the outputs; the monitor summarised the latency.
    let bag = node::bag::BagReader::open(tmp.join("out/drive.mcap")).unwrap();
    let topics: Vec<&str> = bag
        .channels()
        .iter()
        .map(|c| c.info.topic.as_str())
        .collect();
    for t in [
        "/stereosplat/left/image",
        "/stereosplat/bin/map",
        "/stereosplat/latency",
    ] {
        assert!(topics.contains(&t), "{t} in {topics:?}");
    }
    let latency: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tmp.join("out/latency.json")).unwrap()).unwrap();
    assert!(latency["bins"].as_u64().unwrap() >= 1, "{latency}");
    let _ = std::fs::remove_dir_all(&tmp);
}

#[test]
fn eval_synthetic_runs_at_a_tiny_size() {
    let dir = scratch("eval_synthetic");
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch/eval_synthetic.toml");
    let data = format!("data={}", dir.join("data").display());
    let out = format!("out={}", dir.join("eval").display());
    let (code, stdout, stderr) = launch(&[
        file.to_str().unwrap(),
        "--set",
        &data,
        "--set",
        &out,
        "--set",
        "frames=20",
        "--set",
        "width=136",
        "--set",
        "height=36",
        "--set",
        "supersample=1",
        "--set",
        "max_bins=1",
    ]);
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    assert!(stdout.contains("[data] wrote"), "{stdout}");
    assert!(
        dir.join("eval").read_dir().unwrap().next().is_some(),
        "eval wrote nothing"
    );
}

#[test]
fn an_optional_failure_lets_the_rest_finish_but_fails_the_launch() {
    let dir = scratch("optional");
    let file = write(
        &dir,
        "optional.toml",
        r#"
[[process]]
name = "flaky"
program = "sh"
args = ["-c", "exit 4"]
required = false

[[process]]
name = "worker"
program = "sh"
args = ["-c", "sleep 0.3; echo done"]
oneshot = true
"#,
    );
    let (code, stdout, stderr) = launch(&[file.to_str().unwrap()]);
    assert!(stdout.lines().any(|l| l == "[worker] done"), "{stdout}");
    assert_eq!(code, 4, "{stderr}");
    assert!(
        stderr.contains("launch: process `flaky` failed: exit status: 4"),
        "{stderr}"
    );
}

#[test]
fn a_required_process_ending_well_ends_the_launch_well() {
    let dir = scratch("required_end");
    let file = write(
        &dir,
        "end.toml",
        r#"
[[process]]
name = "server"
program = "sh"
args = ["-c", "echo up; exec sleep 30"]

[[process]]
name = "replay"
program = "sh"
args = ["-c", "echo played"]
after = [{ process = "server", line = "up" }]
"#,
    );
    let (code, stdout, stderr) = launch(&[file.to_str().unwrap()]);
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("[replay] played"), "{stdout}");
    assert!(
        stderr.contains("required process replay ended, stopping the others"),
        "{stderr}"
    );
    assert!(stderr.contains("server exited: signal: 15"), "{stderr}");
}

/// The node, a router and two worker processes through the launcher: every process is a
/// client of the router (nobody connects to anybody else), the node runs no reconstructor,
/// and both workers make bins.
#[test]
fn the_workers_launch_file_makes_every_bin_on_workers_through_a_router() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let tmp = std::env::temp_dir().join(format!("stereosplat-workers-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let mut args = vec![root.join("launch/node_workers.toml").display().to_string()];
    for (k, v) in [
        ("data", tmp.join("data").display().to_string()),
        ("out", tmp.join("out").display().to_string()),
        (
            "router",
            format!("tcp/127.0.0.1:{}", net_support::free_port()),
        ),
        ("frames", "40".into()),
        ("width", "136".into()),
        ("height", "40".into()),
        // As fast as possible: the bins come together, so both workers get some.
        ("rate", "0".into()),
        ("queue", "64".into()),
    ] {
        args.extend(["--set".to_string(), format!("{k}={v}")]);
    }
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let (code, stdout, stderr) = launch(&refs);
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    assert!(stdout.contains("[replay] replayed 40 frames"), "{stdout}");
    let summary: serde_json::Value = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("[node] "))
        .find_map(|l| serde_json::from_str(l).ok())
        .unwrap_or_else(|| panic!("the node's summary: {stdout}"));
    let counter = |k: &str| summary["counters"][k].as_u64().unwrap_or(0);
    let published = summary["bins_published"].as_u64().unwrap();
    assert!(published >= 2, "{summary}");
    assert_eq!(counter("workers/joined"), 2, "{summary}");
    assert!(
        counter("workers/bins/a") > 0 && counter("workers/bins/b") > 0,
        "{summary}"
    );
    assert_eq!(
        counter("workers/bins/a") + counter("workers/bins/b"),
        published
    );
    assert_eq!(counter("dropped/worker_queue"), 0);
    // The workers and the router outlived the node (`stop_after`): nothing was left.
    assert_eq!(counter("dropped/at_stop"), 0);
    assert!(tmp.join("out/global_map.ply").exists());
    let _ = std::fs::remove_dir_all(&tmp);
}
