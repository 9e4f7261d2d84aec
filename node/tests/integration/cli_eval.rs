//! The data and evaluation commands end to end, as a user runs them: a held-out synthetic
//! drive is written in the KITTI-360 layout, then the classical baseline is evaluated on it
//! with the paper's protocol (LPIPS on by default, then off), and the table, JSON and
//! pictures are checked.

use std::path::Path;

use crate::cli_support;

use cli_support::{stereosplat, temp_dir};

#[test]
fn synth_then_eval_writes_the_papers_table_for_the_baseline() {
    let data = temp_dir("eval-data");
    let out = temp_dir("eval-out");
    let size = ["--frames", "40", "--width", "272", "--height", "72"];
    stereosplat(
        &[&["synth-heldout"][..], &size, &["--out"]].concat(),
        &[&data],
    );
    let seq = data.join("data_2d_raw/synth_drive_1000000_sync/image_00/data_rect");
    assert_eq!(std::fs::read_dir(&seq).unwrap().count(), 40);

    let table = stereosplat(
        &[
            "eval",
            "--method",
            "sgm",
            "--max-bins",
            "4",
            "--pictures",
            "1",
            "--data",
        ],
        &[&data, Path::new("--out"), &out],
    );
    assert!(table.contains("| sgm |"), "{table}");
    assert!(table.contains("| first LPIPS |"), "{table}");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("eval.json")).unwrap()).unwrap();
    assert_eq!(json["bins"].as_array().unwrap().len(), 4);
    assert!(json["skipped"].as_array().unwrap().is_empty());
    let first = &json["summary"]["first"];
    let last = &json["summary"]["last"];
    let num = |v: &serde_json::Value| v.as_f64().unwrap();
    // The input view re-rendered is the easiest frame; the last one, 8 m on, the hardest.
    assert!(num(&first["psnr"]) > num(&last["psnr"]), "{json}");
    assert!(num(&first["psnr"]) > 15.0, "{json}");
    assert!(num(&first["abs_rel"]) < 0.2, "{json}");
    assert!(num(&first["lpips"]) < num(&last["lpips"]), "{json}");
    assert!(num(&last["lpips"]) < 1.0, "{json}");
    let pictures = std::fs::read_dir(out.join("pictures")).unwrap().count();
    assert_eq!(pictures, 3, "first, centre and last of one bin");

    let table = stereosplat(
        &[
            "eval",
            "--method",
            "sgm",
            "--no-lpips",
            "--max-bins",
            "1",
            "--data",
        ],
        &[&data, Path::new("--out"), &out],
    );
    assert!(
        table.contains("| sgm |") && !table.contains("LPIPS"),
        "{table}"
    );
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("eval.json")).unwrap()).unwrap();
    assert!(json["summary"]["first"]["lpips"].is_null(), "{json}");
    let _ = std::fs::remove_dir_all(&data);
    let _ = std::fs::remove_dir_all(&out);
}
