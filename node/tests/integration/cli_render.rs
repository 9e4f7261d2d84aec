//! The `stereosplat` binary end to end: `render` on the generated scene and the render
//! benchmark's JSON (docs/evaluation.md, "The renderer: `render` and `bench render`"), run as
//! a user runs them.

use std::process::Command;

fn stereosplat() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stereosplat"))
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("stereosplat-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn render_writes_the_scene_and_its_pictures_on_both_rasterizers() {
    for (flag, name) in [(None, "gpu"), (Some("--cpu"), "cpu")] {
        let out = temp_dir(&format!("render-{name}"));
        let mut cmd = stereosplat();
        cmd.args(["render", "--width", "96", "--height", "40", "--out"])
            .arg(&out);
        cmd.args(flag);
        let run = cmd.output().unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let set = renderer::ply::load_ply(out.join("scene.ply")).unwrap();
        assert_eq!(set.len(), 2 * 96 * 40);
        for png in ["rgb.png", "depth.png", "alpha.png"] {
            let img = image::open(out.join(png)).unwrap();
            assert_eq!((img.width(), img.height()), (96, 40), "{png}");
        }
        let _ = std::fs::remove_dir_all(&out);
    }
}

#[test]
fn bench_render_prints_json_with_cpu_and_gpu_timings() {
    let run = stereosplat()
        .args([
            "bench",
            "render",
            "--scene",
            "random",
            "--gaussians",
            "2000",
        ])
        .args([
            "--width", "128", "--height", "64", "--runs", "2", "--warmup", "1",
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(json["gaussians"], 2000);
    assert!(json["cpu"]["forward"]["median_ms"].as_f64().unwrap() > 0.0);
    assert!(json["cpu"]["backward"]["min_ms"].as_f64().unwrap() > 0.0);
    assert!(json["gpu"]["forward"]["median_ms"].as_f64().unwrap() > 0.0);
    assert!(!json["gpu"]["adapter"].as_str().unwrap().is_empty());
    let diff = json["gpu"]["max_abs_rgb_diff_vs_cpu"].as_f64().unwrap();
    assert!(diff <= 2e-3, "GPU and CPU renders differ by {diff}");
}

#[test]
fn a_missing_ply_is_a_clear_error_not_a_panic() {
    let run = stereosplat()
        .args(["render", "--ply", "/nonexistent/map.ply", "--cpu"])
        .output()
        .unwrap();
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains("map.ply") || err.to_lowercase().contains("no such file"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}
