//! The learned model's commands end to end, as a user runs them: `train` (and `--resume`) on
//! a small generated drive, `eval --method stereosplat` with the shipped tiny weights and
//! 2 input pairs, and `bench model`'s JSON (with and without the volume branch).

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::cli_support;

use cli_support::{stereosplat, temp_dir};

/// A 40-frame held-out drive at 136x40.
fn drive(name: &str) -> PathBuf {
    let data = temp_dir(name);
    stereosplat(
        &[
            "research",
            "synth-heldout",
            "--frames",
            "40",
            "--width",
            "136",
            "--height",
            "40",
            "--out",
        ],
        &[&data],
    );
    data
}

#[test]
fn train_writes_checkpoint_log_curve_and_resumes() {
    let data = drive("model-train-data");
    let out = temp_dir("model-train-out");
    let train = |steps: &str, resume: bool| {
        let mut args = vec![
            "research",
            "train",
            "--steps",
            steps,
            "--checkpoint-every",
            "2",
        ];
        args.extend(["--targets", "1", "--max-pairs", "2"]);
        if resume {
            args.push("--resume");
        }
        args.push("--data");
        stereosplat(&args, &[&data, Path::new("--out"), &out])
    };
    train("2", false);
    let printed = train("3", true);
    assert!(printed.contains("step 3"), "{printed}");
    let log = std::fs::read_to_string(out.join("log.csv")).unwrap();
    assert_eq!(log.lines().count(), 4, "{log}");
    for file in [
        "checkpoint/weights.safetensors",
        "checkpoint/optimizer.safetensors",
        "checkpoint/state.json",
        "loss_curve.png",
        "stereosplat_tiny.safetensors",
    ] {
        assert!(out.join(file).exists(), "{file}");
    }
    // A mix takes one bin length for all roots or one per root, nothing else.
    let mixed = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
        .args(["research", "train", "--steps", "1", "--data"])
        .args([&data, Path::new("--data"), &data, Path::new("--out"), &out])
        .args([
            "--bin-length",
            "8",
            "--bin-length",
            "4",
            "--bin-length",
            "2",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&mixed.stderr);
    assert!(!mixed.status.success(), "{stderr}");
    assert!(
        stderr.contains("3 --bin-length values for 2 --data roots"),
        "{stderr}"
    );
    // A bin must span a positive, finite distance, for training and for the enhancer's pairs.
    for (command, length) in [
        ("train", "-1"),
        ("enhancer-data", "0"),
        ("enhancer-data", "NaN"),
    ] {
        let refused = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
            .args(["research", command, "--data"])
            .args([&data, Path::new("--out"), &out])
            .arg(format!("--bin-length={length}"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert!(!refused.status.success(), "{command} {length}: {stderr}");
        assert!(
            stderr.contains("a bin must span a positive distance"),
            "{command} {length}: {stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&data);
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn eval_runs_the_shipped_weights_with_two_pairs() {
    let data = drive("model-eval-data");
    let out = temp_dir("model-eval-out");
    let table = stereosplat(
        &[
            "research",
            "eval",
            "--method",
            "stereosplat",
            "--pairs",
            "2",
            "--max-bins",
            "2",
            "--pictures",
            "0",
            "--no-lpips",
            "--data",
        ],
        &[&data, Path::new("--out"), &out],
    );
    assert!(table.contains("| stereosplat-tiny |"), "{table}");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("eval.json")).unwrap()).unwrap();
    let bins = json["bins"].as_array().unwrap();
    assert_eq!(bins.len(), 2);
    for bin in bins {
        assert!(bin["gaussians"].as_u64().unwrap() > 0);
    }
    let psnr = json["summary"]["average"]["psnr"].as_f64().unwrap();
    assert!(psnr.is_finite() && psnr > 5.0, "{psnr}");
    let _ = std::fs::remove_dir_all(&data);
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn bench_model_prints_json_per_preset() {
    let cache = temp_dir("model-bench");
    let printed = stereosplat(
        &[
            "bench", "model", "--preset", "tiny", "--width", "136", "--height", "40", "--runs",
            "1", "--warmup", "0", "--cache",
        ],
        &[&cache],
    );
    let report: serde_json::Value = serde_json::from_str(printed.trim()).unwrap();
    assert_eq!(report["preset"], "tiny");
    assert!(report["parameters"].as_u64().unwrap() > 100_000);
    assert!(report["gaussians"].as_u64().unwrap() > 0);
    assert!(report["median_ms"].as_f64().unwrap() > 0.0);
    assert_eq!(report["volume_branch"], false);
    assert_eq!(report["cost_volume_gaussians"], report["gaussians"]);
    // With the volume branch: the shipped weights for the cost-volume part, the branch
    // untrained, each branch's time and Gaussians.
    let printed = stereosplat(
        &[
            "bench",
            "model",
            "--preset",
            "tiny",
            "--width",
            "136",
            "--height",
            "40",
            "--runs",
            "1",
            "--warmup",
            "0",
            "--set",
            "volume_branch=true",
            "--set",
            "volume.top_k=256",
            "--cache",
        ],
        &[&cache],
    );
    let report: serde_json::Value = serde_json::from_str(printed.trim()).unwrap();
    assert_eq!(report["volume_branch"], true);
    assert!(report["weights"]
        .as_str()
        .unwrap()
        .ends_with("+ untrained volume"));
    assert!(report["volume_median_ms"].as_f64().unwrap() > 0.0);
    let count = |k: &str| report[k].as_u64().unwrap();
    assert!(count("cost_volume_gaussians") > 0);
    assert_eq!(
        count("cost_volume_gaussians") + count("volume_gaussians"),
        count("gaussians")
    );
    let _ = std::fs::remove_dir_all(&cache);
}

#[test]
fn a_node_whose_reconstructor_cannot_be_made_fails_at_once_and_says_why() {
    // The progressive pass with an enhancer file that does not exist: `demo` (the node on
    // loopback) must exit with the reason, not wait for a node that never started.
    let out = temp_dir("demo-no-enhancer");
    let missing = out.join("no-such-enhancer.safetensors");
    let setting = format!("enhancer_weights={}", missing.display());
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_stereosplat"))
        .args(["demo", "--frames", "12", "--width", "136", "--height", "40"])
        .args(["--preset", "tiny-plus", "--set", &setting, "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("enhancer weights") && stderr.contains("enhancer=false"),
        "{stderr}"
    );
}
