//! `stereosplat replay --data` over a drive with a corrupt PNG, run as a user runs it: the
//! frame is named on stderr with its file and the decoder's reason, the other frames are
//! still replayed, and the command exits non-zero; with `--allow-skipped` it exits 0 and
//! still names the file. The replay listens on a free loopback port and publishes to no one.

use crate::net_support;

use std::process::Command;

use model::frame::Side;
use model::generate::write_synthetic;
use model::kitti360::layout;
use model::synth::SynthConfig;

/// Runs `stereosplat replay` on `data` with `extra` flags: (exit code, stdout, stderr).
fn replay(data: &std::path::Path, extra: &[&str]) -> (Option<i32>, String, String) {
    let listen = format!("tcp/127.0.0.1:{}", net_support::free_port());
    let out = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
        .args([
            "replay", "--rate", "0", "--warmup", "0", "--listen", &listen,
        ])
        .args(["--namespace", "clireplay", "--data"])
        .arg(data)
        .args(extra)
        .output()
        .unwrap();
    let text = |b: Vec<u8>| String::from_utf8_lossy(&b).into_owned();
    (out.status.code(), text(out.stdout), text(out.stderr))
}

/// A fresh path under the temp dir, unique to this process.
fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("stereosplat-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn a_corrupt_png_is_named_and_fails_the_replay() {
    let root = temp_dir("clireplay");
    let config = SynthConfig {
        seed: 3,
        frames: 4,
        width: 64,
        height: 24,
        lidar_azimuth_steps: 16,
        ..SynthConfig::default()
    };
    let seq = write_synthetic(&root, &config, &mut |_, _| {}).unwrap();
    let bad = layout::image(&root, &seq, Side::Right, 2);
    let bytes = std::fs::read(&bad).unwrap();
    std::fs::write(&bad, &bytes[..bytes.len() / 2]).unwrap();
    let shown = bad.display().to_string();

    let (code, stdout, stderr) = replay(&root, &[]);
    assert_eq!(code, Some(1), "stdout: {stdout}\nstderr: {stderr}");
    assert!(stdout.contains("replayed 3 frames") && stdout.contains("(1 skipped)"));
    for needle in [shown.as_str(), "bad PNG", "frame 2", "1 of 4 frames"] {
        assert!(stderr.contains(needle), "`{needle}` in: {stderr}");
    }

    let (code, _, stderr) = replay(&root, &["--allow-skipped"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.contains(&shown), "{stderr}");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_missing_data_root_names_the_path() {
    let root = temp_dir("clireplay-missing");
    let (code, _, stderr) = replay(&root, &[]);
    assert_ne!(code, Some(0));
    assert!(stderr.contains(&root.display().to_string()), "{stderr}");
}
