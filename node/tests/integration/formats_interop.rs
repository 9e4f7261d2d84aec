//! The node's SPZ and glTF files in readers no one here wrote (`interop/`, pinned npm
//! packages that `.ci/setup` installs):
//! - PlayCanvas `splat-transform` (its CLI, under Node.js) converts the node's SPZ to PLY, and
//!   every value it decoded equals what was written within SPZ's quantisation, per field (see
//!   [`spz_tolerances`]);
//! - Babylon.js's own glTF loader (`KHR_gaussian_splatting`), in Debian's headless Chromium
//!   through playwright-core (`interop/render.mjs`), loads a bin map that `stereosplat demo
//!   --format glb` wrote, and Spark (`@sparkjsdev/spark` on three.js) loads the same bin
//!   exported to SPZ by `stereosplat export`; each renders it from the bin's camera, and the
//!   render matches the CPU rasterizer's render of the same map (as read back from that file)
//!   at [`MIN_PSNR_DB`] or more, as `view_page` asks of the live view.
//!
//! Without Node.js, Chromium or `interop/node_modules` these tests fail and say what to
//! install; they never pass silently.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{Quat, Vec3};
use model::kitti360::Calibration;
use renderer::formats::{save_map, MapFormat};
use renderer::ply::SH_C0;
use renderer::{scene, Camera, GaussianSet, Intrinsics};

use crate::cli_support::{stereosplat, temp_dir};
use crate::view_page::{score_shot, ShotScore};

/// Least PSNR (dB, 8-bit RGB) between a viewer's render of the map file and the CPU reference's
/// render of the same map and camera; the same bar as the live view's check (`view_page`),
/// for the same reasons (8-bit colours in the viewer, its own cut-off and sort order).
const MIN_PSNR_DB: f64 = 30.0;
/// Least fraction of a viewer's canvas that must be lit (any channel above 8/255).
const MIN_LIT: f64 = 0.2;

fn interop() -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../interop")).to_path_buf()
}

/// Panics with what to install when Node.js or the pinned packages are missing.
fn require_interop(package: &str) {
    let node = Command::new("node").arg("--version").output();
    assert!(
        node.is_ok_and(|o| o.status.success()),
        "Node.js is missing: install it (apt `nodejs`), then `bash .ci/setup`"
    );
    assert!(
        interop().join("node_modules").join(package).is_dir(),
        "interop/node_modules/{package} is missing: run `bash .ci/setup` (npm ci in interop/)"
    );
}

/// SPZ's quantisation, the most each field may differ after a round trip through it
/// (half a step of each 8-, 9- or 24-bit code, plus float rounding):
/// position 0.5 / 2^12 m (12 fractional bits); log-scale 0.5 / 16; opacity 0.5 / 255;
/// colour half of SH_C0 / (0.15 * 255) = 0.0037; rotation 1 - |q . q'| below 5e-6 (9-bit
/// magnitudes of the smallest three components, each within 7e-4).
struct Tolerances {
    position: f32,
    log_scale: f32,
    opacity: f32,
    colour: f32,
    rotation: f32,
}

fn spz_tolerances() -> Tolerances {
    Tolerances {
        position: 0.5 / 4096.0 + 1e-6,
        log_scale: 0.5 / 16.0 + 1e-5,
        // splat-transform writes opacity as a logit with its own 1e-6 clamp; the sigmoid of
        // that is within 1e-6 of the code's value.
        opacity: 0.5 / 255.0 + 2e-6,
        colour: (0.5 * SH_C0 / (0.15 * 255.0)) as f32 + 1e-5,
        rotation: 5e-6,
    }
}

/// Generated Gaussians with rotations of every kind and colours over the whole range.
fn street() -> GaussianSet {
    let mut set = scene::random_in_view(11, 3000, &Intrinsics::from_hfov(320, 96, 80.0));
    for (i, q) in set.rotations.iter_mut().enumerate() {
        let axis = Vec3::new(0.4, (i % 9) as f32 - 4.0, 1.0).normalize();
        *q = Quat::from_axis_angle(axis, i as f32 * 0.61 - 3.0);
    }
    for (i, c) in set.colors.iter_mut().enumerate() {
        *c = Vec3::new((i % 101) as f32 / 100.0, c.y, 1.0 - (i % 37) as f32 / 36.0);
    }
    set
}

#[test]
fn splat_transform_decodes_our_spz_to_the_values_we_wrote() {
    require_interop("@playcanvas/splat-transform");
    let dir = temp_dir("spz-interop");
    std::fs::create_dir_all(&dir).unwrap();
    let set = street();
    let spz = dir.join("map.spz");
    save_map(&set, &spz, MapFormat::Spz).unwrap();
    let ply = dir.join("from_spz.ply");
    let cli = interop().join("node_modules/@playcanvas/splat-transform/bin/cli.mjs");
    let run = Command::new("node")
        .arg(&cli)
        .arg("-w")
        .arg(&spz)
        .arg(&ply)
        .output()
        .expect("node runs");
    assert!(
        run.status.success(),
        "splat-transform failed:\n{}{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    let back = renderer::ply::load_ply(&ply).expect("splat-transform's PLY reads");
    assert_eq!(back.len(), set.len());
    let t = spz_tolerances();
    let mut worst = [0.0f32; 5];
    for i in 0..set.len() {
        let (a, b) = (set.get(i), back.get(i));
        let e = [
            (a.mean - b.mean).abs().max_element(),
            (a.log_scale - b.log_scale).abs().max_element(),
            (a.opacity - b.opacity).abs(),
            (a.color - b.color).abs().max_element(),
            1.0 - a.rotation.normalize().dot(b.rotation.normalize()).abs(),
        ];
        for (w, v) in worst.iter_mut().zip(e) {
            *w = w.max(v);
        }
    }
    println!("splat-transform SPZ -> PLY, largest differences: position {} m, log-scale {}, opacity {}, colour {}, rotation 1-|dot| {}",
        worst[0], worst[1], worst[2], worst[3], worst[4]);
    let limits = [t.position, t.log_scale, t.opacity, t.colour, t.rotation];
    let names = ["position", "log-scale", "opacity", "colour", "rotation"];
    for ((w, l), name) in worst.iter().zip(limits).zip(names) {
        assert!(w <= &l, "{name}: {w} beyond SPZ's {l}");
    }
    // The quantisation is really there (a file that stored floats would differ by ~0).
    assert!(worst[0] > 1e-5 && worst[3] > 1e-3, "{worst:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn babylon_and_spark_render_a_bin_map_like_the_cpu_rasterizer() {
    require_interop("babylonjs-loaders");
    require_interop("@sparkjsdev/spark");
    require_interop("playwright-core");
    assert!(
        Path::new("/usr/bin/chromium").is_file(),
        "Chromium is missing: apt `chromium` (`bash .ci/setup`)"
    );
    let out = temp_dir("viewers-interop");
    let (w, h) = ("192", "56");
    let demo = stereosplat(
        &[
            "demo",
            "--frames",
            "20",
            "--width",
            w,
            "--height",
            h,
            "--method",
            "sgm",
            "--renders",
            "off",
            "--rate",
            "0",
            "--format",
            "glb",
            "--out",
        ],
        &[&out],
    );
    assert!(demo.contains("global_map.glb"), "{demo}");
    assert!(out.join("map/global_map.glb").is_file());
    let glb = out.join("bins/bin_0000.glb");
    // The same bin as SPZ, through `export`.
    let spz = out.join("bins/bin_0000.spz");
    let exported = stereosplat(&["export", "--format", "spz", "--map"], &[&glb]);
    let exported: serde_json::Value = serde_json::from_str(exported.trim()).unwrap();
    assert_eq!(exported["out"].as_str(), spz.to_str(), "{exported}");
    // The bin frame is its first camera's: the camera is the identity there.
    let k = Calibration::read(&out.join("drive"))
        .unwrap()
        .rig()
        .unwrap()
        .intrinsics;
    let camera = Camera::identity(k);
    for (viewer, file, format) in [
        ("babylon", &glb, MapFormat::Glb),
        ("spark", &spz, MapFormat::Spz),
    ] {
        let (seen, set) = renderer::formats::load_map(file).expect("the bin map reads back");
        assert_eq!(seen, format);
        assert!(set.len() > 1000, "{} Gaussians", set.len());
        assert_eq!(exported["gaussians"].as_u64(), Some(set.len() as u64));
        let (psnr, psnr_off) = viewer_psnr(viewer, file, &set, &camera, &out.join(viewer));
        assert!(
            psnr >= MIN_PSNR_DB,
            "{viewer}: PSNR {psnr:.2} dB < {MIN_PSNR_DB}"
        );
        assert!(
            psnr > psnr_off,
            "{viewer}: the true camera ({psnr:.2} dB) is no better than one a pixel off ({psnr_off:.2} dB)"
        );
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// Renders `file` in `viewer` (`interop/render.mjs`) from `camera` and returns the PSNR of its
/// canvas against the CPU rasterizer's render of `set`, at the camera and at the camera one
/// pixel off; checks the viewer loaded every Gaussian, asked for nothing but its own files, and
/// drew a canvas that is not blank.
fn viewer_psnr(
    viewer: &str,
    file: &Path,
    set: &GaussianSet,
    camera: &Camera,
    shots: &Path,
) -> (f64, f64) {
    let k = camera.intrinsics;
    let pinhole = format!(
        "{},{},{},{},{},{}",
        k.fx, k.fy, k.cx, k.cy, k.width, k.height
    );
    let run = Command::new("node")
        .arg(interop().join("render.mjs"))
        .args(["--viewer", viewer, "--map"])
        .arg(file)
        .arg("--out")
        .arg(shots)
        .args(["--pinhole", &pinhole])
        .output()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "render.mjs --viewer {viewer} failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_str(stdout.lines().last().unwrap()).expect("one JSON line");
    assert_eq!(summary["meshes"], 1, "{summary}");
    // Babylon reports its splat count rounded up to whole rows of 16 (its data textures).
    let count = summary["count"].as_u64().unwrap_or(0) as usize;
    let want = match viewer {
        "babylon" => set.len().next_multiple_of(16),
        _ => set.len(),
    };
    assert_eq!(count, want, "{summary}");
    assert_eq!(summary["outside"], serde_json::json!([]), "{summary}");

    let ShotScore {
        lit,
        psnr,
        mad,
        psnr_off,
        ..
    } = score_shot(&shots.join(format!("{viewer}.png")), set, camera);
    assert!(
        lit >= MIN_LIT,
        "{viewer}'s canvas is nearly blank: {lit:.3} lit"
    );
    println!(
        "{viewer} vs CPU reference: PSNR {psnr:.2} dB, mean abs {mad:.2}/255, lit {lit:.3}; one pixel off: {psnr_off:.2} dB"
    );
    (psnr, psnr_off)
}
