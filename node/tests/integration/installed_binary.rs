//! The binary works where it is installed: copied into an empty folder, far from the checkout,
//! with a fresh home, `reconstruct` runs the learned model on the embedded weights (read from
//! memory: nothing is written under the home folder); a folder named by `STEREOSPLAT_WEIGHTS`
//! takes precedence, and a bad file there is named in the error; a preset with no shipped
//! weights says how to train them.

use std::path::Path;
use std::process::Command;

use crate::cli_reconstruct::{rig_flags, synthetic_pair};
use crate::cli_support::temp_dir;

/// Runs the binary at `exe` in `cwd` with `home` as its home and cache, `weights` as
/// `STEREOSPLAT_WEIGHTS` when given: success and stderr.
fn run(
    exe: &Path,
    cwd: &Path,
    home: &Path,
    weights: Option<&Path>,
    args: &[String],
) -> (bool, String) {
    let mut cmd = Command::new(exe);
    cmd.args(args)
        .current_dir(cwd)
        .env("HOME", home)
        .env("XDG_CACHE_HOME", home.join("cache"))
        .env_remove("STEREOSPLAT_WEIGHTS");
    if let Some(w) = weights {
        cmd.env("STEREOSPLAT_WEIGHTS", w);
    }
    let out = cmd.output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_copied_binary_runs_the_learned_model_on_its_embedded_weights() {
    let (left, right, seq) = synthetic_pair("installed-pair");
    let root = temp_dir("installed-binary");
    let (bin, cwd, home) = (root.join("bin"), root.join("work"), root.join("home"));
    for d in [&bin, &cwd, &home] {
        std::fs::create_dir_all(d).unwrap();
    }
    let exe = bin.join("stereosplat");
    std::fs::copy(env!("CARGO_BIN_EXE_stereosplat"), &exe).unwrap();
    let mut args: Vec<String> = ["reconstruct", "--left"].map(String::from).to_vec();
    args.push(left.display().to_string());
    args.push("--right".into());
    args.push(right.display().to_string());
    args.extend(rig_flags(&seq));
    args.extend(["--out".into(), cwd.join("out").display().to_string()]);

    let (ok, err) = run(&exe, &cwd, &home, None, &args);
    assert!(ok, "{err}");
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(cwd.join("out/summary.json")).unwrap()).unwrap();
    assert!(summary["gaussians"].as_u64().unwrap() > 1000, "{summary}");
    // The embedded weights are read from memory: nothing is written under the home folder.
    assert_eq!(std::fs::read_dir(&home).unwrap().count(), 0);

    // A preset that ships no weights is an error that says how to get them.
    let mut small = args.clone();
    small.extend(["--preset".into(), "small".into()]);
    let (ok, err) = run(&exe, &cwd, &home, None, &small);
    assert!(!ok && err.contains("stereosplat research train"), "{err}");

    // A folder of weights named by the environment comes first: a bad file there is named.
    let override_dir = root.join("weights");
    std::fs::create_dir_all(&override_dir).unwrap();
    let bad = override_dir.join("stereosplat_tiny.safetensors");
    std::fs::write(&bad, b"not safetensors").unwrap();
    let (ok, err) = run(&exe, &cwd, &home, Some(&override_dir), &args);
    assert!(!ok && err.contains(&bad.display().to_string()), "{err}");
    let _ = std::fs::remove_dir_all(&root);
}
