//! What the tests that run Python share: the check that `python3` imports the packages a
//! script needs, failing with the install command when it does not, plain or with the ROS 2
//! paths of `scripts/ros2_env.sh`, and running a script that answers a JSON request.

/// How to get the packages.
pub const INSTALL: &str = "run `pip install -r scripts/requirements.txt` (CI does it in .ci/setup)";

/// How to get the ROS 2 message packages no wheel ships.
pub const INSTALL_ROS2: &str =
    "run `pip install -r scripts/requirements.txt` and `bash scripts/ros2_msgs.sh` (CI does both in .ci/setup)";

/// `scripts/ros2_env.sh`: runs a command with the ROS 2 wheels and generated packages on its
/// paths.
pub const ROS2_ENV: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/ros2_env.sh");

/// Panics with [`INSTALL`] unless `python3` can `import <modules>` (comma separated).
pub fn require(modules: &str) {
    probe(&["python3"], modules, INSTALL);
}

/// Panics with [`INSTALL_ROS2`] unless `python3` run through [`ROS2_ENV`] can `import
/// <modules>`.
pub fn require_ros2(modules: &str) {
    probe(&["bash", ROS2_ENV, "python3"], modules, INSTALL_ROS2);
}

fn probe(python: &[&str], modules: &str, install: &str) {
    let probe = std::process::Command::new(python[0])
        .args(&python[1..])
        .args(["-c", &format!("import {modules}")])
        .output();
    match probe {
        Ok(out) if out.status.success() => {}
        Ok(out) => panic!(
            "python3 cannot import {modules}: {install}\n{}",
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => panic!("cannot run python3 ({e}): install Python 3, then {install}"),
    }
}

/// Runs `command` (e.g. `["python3", script]`) with `request` as JSON on stdin and returns
/// the JSON it prints, failing with its stderr when it exits non-zero. (Not every test that
/// includes this module calls it.)
pub fn run_json(command: &[&str], request: &serde_json::Value) -> serde_json::Value {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let mut child = Command::new(command[0])
        .args(&command[1..])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 starts");
    let body = serde_json::to_vec(request).expect("request serialises");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(&body)
        .expect("request written");
    let out = child.wait_with_output().expect("script runs");
    assert!(
        out.status.success(),
        "{command:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("the script prints JSON")
}
