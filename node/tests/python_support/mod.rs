//! What the tests that run Python share: the check that `python3` imports the packages a
//! script needs, failing with the install command when it does not.

/// How to get the packages.
pub const INSTALL: &str = "run `pip install -r scripts/requirements.txt` (CI does it in .ci/setup)";

/// Panics with [`INSTALL`] unless `python3` can `import <modules>` (comma separated).
pub fn require(modules: &str) {
    let probe = std::process::Command::new("python3")
        .args(["-c", &format!("import {modules}")])
        .output();
    match probe {
        Ok(out) if out.status.success() => {}
        Ok(out) => panic!(
            "python3 cannot import {modules}: {INSTALL}\n{}",
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => panic!("cannot run python3 ({e}): install Python 3, then {INSTALL}"),
    }
}
