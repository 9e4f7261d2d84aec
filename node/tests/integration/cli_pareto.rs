//! `bench pareto` and `eval-map` end to end on a small generated held-out drive, as a user
//! runs them: two operating points (SGM and the shipped `tiny`) plus one whose weights do
//! not exist, then the fused map's sweep; the JSON's figures are finite, the fronts are the
//! ones the figures imply, the missing point is listed, the chart and pictures exist.

use std::path::Path;

use crate::cli_support;

use cli_support::{stereosplat, temp_dir};
use serde_json::Value;

fn num(v: &Value) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("{v} is not a finite number"))
}

#[test]
fn bench_pareto_and_eval_map_on_a_small_drive() {
    let data = temp_dir("pareto-data");
    let out = temp_dir("pareto-out");
    std::fs::create_dir_all(&out).unwrap();
    let size = ["--frames", "40", "--width", "272", "--height", "72"];
    stereosplat(
        &[&["research", "synth-heldout"][..], &size, &["--out"]].concat(),
        &[&data],
    );
    let points = out.join("points.toml");
    std::fs::write(
        &points,
        "[[point]]\nname = \"sgm\"\nmethod = \"sgm\"\n\n\
         [[point]]\nname = \"tiny\"\n\n\
         [[point]]\nname = \"ghost\"\nweights = \"/nonexistent/ghost.safetensors\"\n",
    )
    .unwrap();
    let stdout = stereosplat(
        &[
            "bench",
            "pareto",
            "--no-lpips",
            "--max-bins",
            "2",
            "--points",
        ],
        &[
            &points,
            Path::new("--data"),
            &data,
            Path::new("--out"),
            &out,
        ],
    );
    let json: Value = serde_json::from_str(&stdout).unwrap();
    let on_disk: Value =
        serde_json::from_slice(&std::fs::read(out.join("pareto.json")).unwrap()).unwrap();
    assert_eq!(json, on_disk);
    let pts = json["points"].as_array().unwrap();
    assert_eq!(pts.len(), 2, "{json}");
    assert_eq!(json["skipped"][0]["name"], "ghost");
    for p in pts {
        assert_eq!(p["bins"], 2, "{p}");
        for key in [
            "latency_median_ms",
            "latency_p90_ms",
            "peak_rss_mib",
            "gaussians_per_bin",
            "psnr",
            "ssim",
            "abs_rel",
            "sq_rel",
        ] {
            assert!(num(&p[key]).is_finite(), "{key}: {p}");
        }
        assert!(num(&p["latency_p90_ms"]) >= num(&p["latency_median_ms"]));
        assert!(num(&p["peak_rss_mib"]) > 10.0, "{p}");
        assert!(num(&p["gaussians_per_bin"]) > 100.0, "{p}");
        assert!(p["lpips"].is_null());
    }
    // The fronts as the figures imply: a point is off a front only when the other is at
    // least as fast and at least as good.
    let (a, b) = (&pts[0], &pts[1]);
    let dominates = |x: &Value, y: &Value, key: &str, higher: bool| {
        let (qx, qy) = (num(&x[key]), num(&y[key]));
        let (lx, ly) = (num(&x["latency_median_ms"]), num(&y["latency_median_ms"]));
        let better_eq = if higher { qx >= qy } else { qx <= qy };
        lx <= ly && better_eq && (lx < ly || qx != qy)
    };
    for (key, flag, higher) in [
        ("psnr", "front_psnr", true),
        ("abs_rel", "front_abs_rel", false),
    ] {
        assert_eq!(a[flag], !dominates(b, a, key, higher), "{key}: {json}");
        assert_eq!(b[flag], !dominates(a, b, key, higher), "{key}: {json}");
    }
    let md = std::fs::read_to_string(out.join("pareto.md")).unwrap();
    assert!(md.contains("| sgm |") && md.contains("| tiny |") && md.contains("ghost"));
    let png = image::open(out.join("pareto.png")).unwrap();
    assert_eq!((png.width(), png.height()), (1280, 440));

    // The fused map: two budgets and the keep range swept with SGM's bin maps.
    let map_out = out.join("map");
    let table = stereosplat(
        &[
            "research",
            "eval-map",
            "--method",
            "sgm",
            "--no-lpips",
            "--frame-stride",
            "5",
            "--budgets",
            "2000",
            "--cell-sizes",
            "0.5",
            "--ranges",
            "inf,10",
            "--sky-ranges",
            "10",
            "--confidences",
            "0.5",
            "--data",
        ],
        &[&data, Path::new("--out"), &map_out],
    );
    assert!(table.contains("| default |"), "{table}");
    let json: Value =
        serde_json::from_slice(&std::fs::read(map_out.join("eval_map.json")).unwrap()).unwrap();
    let rows = json["rows"].as_array().unwrap();
    let row = |name: &str| {
        rows.iter()
            .find(|r| r["setting"] == name)
            .unwrap_or_else(|| panic!("no row {name}: {json}"))
    };
    let count = |name: &str| row(name)["gaussians"].as_u64().unwrap();
    assert!(count("budget 2000") <= 2000);
    // The keep rule only ever removes: everything >= the default 20 m >= 10 m.
    assert!(count("range inf") >= count("default"));
    assert!(count("default") >= count("range 10"));
    // The sky layer is drawn behind the same map, not added to it.
    assert_eq!(count("range 10 + sky layer"), count("range 10"));
    assert!(num(&row("range 10 + sky layer")["sky_layer_gaussians"]) > 0.0);
    assert!(row("range 10")["sky_layer_gaussians"].is_null());
    assert!(count("conf 0.5") <= count("default"));
    for r in rows {
        assert!(num(&r["scores"]["mean"]["psnr"]).is_finite(), "{r}");
        assert!(num(&r["gaussians_per_metre"]) > 0.0, "{r}");
    }
    for f in ["eval_map.png", "bev_default.png", "bev_range_inf.png"] {
        assert!(map_out.join(f).exists(), "{f}");
    }
    let side = std::fs::read_dir(&map_out)
        .unwrap()
        .filter(|e| {
            let name = e.as_ref().unwrap().file_name();
            name.to_string_lossy().starts_with("side_default_")
        })
        .count();
    assert_eq!(side, 9, "three frames, three offsets");
    let _ = std::fs::remove_dir_all(&data);
    let _ = std::fs::remove_dir_all(&out);
}
