//! `model::metrics` against scikit-image / NumPy reference values (fixtures written by
//! `scripts/metrics_fixture.py`) and against numbers checked by hand.

use std::path::{Path, PathBuf};

use model::frame::{DepthMap, RgbImage};
use model::metrics::{
    depth_errors, error_map, psnr, ssim, ssim_map, DepthFilter, MetricError, SSIM_WINDOW,
};
use serde_json::Value;

fn fixture_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/metrics")
}

fn reference() -> Value {
    let path = fixture_dir().join("reference.json");
    let text = std::fs::read_to_string(&path).expect("reference.json readable");
    serde_json::from_str(&text).expect("reference.json parses")
}

fn load_png(name: &str) -> RgbImage {
    let img = image::open(fixture_dir().join(name))
        .expect("fixture PNG decodes")
        .to_rgb8();
    RgbImage::from_rgb8(img.width(), img.height(), img.as_raw())
}

fn num(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} is a number"))
}

/// A deterministic textured image: smooth pattern plus a hash "noise" in [0, 1].
fn textured(width: u32, height: u32, seed: u32) -> RgbImage {
    let mut img = RgbImage::new(width, height);
    for (i, v) in img.data.iter_mut().enumerate() {
        let h = (i as u32 ^ seed).wrapping_mul(2_654_435_761) >> 8;
        let noise = (h % 1000) as f32 / 1000.0;
        let smooth = 0.5 + 0.5 * ((i / 3) as f32 * 0.01).sin();
        *v = 0.5 * smooth + 0.5 * noise;
    }
    img
}

fn constant(width: u32, height: u32, value: f32) -> RgbImage {
    RgbImage {
        width,
        height,
        data: vec![value; 3 * width as usize * height as usize],
    }
}

/// The Rust images hold `u8 / 255` in f32; `*_f32` references are skimage on exactly those
/// values, `*_f64` on `u8 / 255` in f64 (the papers' input). The f32 rounding of the
/// inputs (relative 3e-8) moves PSNR by up to ~1e-8 relative, so the f64 comparison for
/// PSNR allows 1e-7; everything else must agree to rounding error.
#[test]
fn psnr_and_ssim_match_scikit_image_on_fixtures() {
    let reference = reference();
    let entries = reference["images"].as_array().expect("images array");
    assert_eq!(entries.len(), 5);
    for entry in entries {
        let name = entry["name"].as_str().expect("name");
        let a = load_png(entry["a"].as_str().expect("a"));
        let b = load_png(entry["b"].as_str().expect("b"));

        let p = psnr(&a, &b).expect("psnr");
        for (key, tol) in [("psnr_f32", 1e-9), ("psnr_f64", 1e-7)] {
            let want = num(entry, key);
            let rel = ((p - want) / want).abs();
            assert!(
                rel < tol,
                "{name} {key}: rust {p} skimage {want} rel {rel:e}"
            );
        }

        let s = ssim(&a, &b).expect("ssim");
        println!(
            "{name}: psnr {p:.9} (f32 ref rel {:.1e}), ssim {s:.9} (f32 ref diff {:.1e}, f64 ref diff {:.1e})",
            ((p - num(entry, "psnr_f32")) / p).abs(),
            (s - num(entry, "ssim_f32")).abs(),
            (s - num(entry, "ssim_f64")).abs()
        );
        for key in ["ssim_f32", "ssim_f64"] {
            let want = num(entry, key);
            assert!(
                (s - want).abs() < 1e-6,
                "{name} {key}: rust {s} skimage {want}"
            );
        }
        // Against the bit-identical input the agreement is far tighter than required.
        assert!((s - num(entry, "ssim_f32")).abs() < 1e-12, "{name}: {s}");
    }
}

/// The full map (channel mean) of the 11 x 13 pair, border included, so scipy's reflect
/// boundary is checked too, not just the interior that enters the mean.
#[test]
fn ssim_map_matches_scikit_image_full_map_with_reflect_border() {
    let reference = reference();
    let entry = reference["images"]
        .as_array()
        .expect("images array")
        .iter()
        .find(|e| e["name"] == "tiny")
        .expect("tiny entry");
    let want: Vec<f64> = entry["ssim_map_f32"]
        .as_array()
        .expect("map array")
        .iter()
        .map(|v| v.as_f64().expect("number"))
        .collect();
    let a = load_png("tiny_a.png");
    let b = load_png("tiny_b.png");
    let map = ssim_map(&a, &b).expect("map");
    assert_eq!((map.width, map.height), (13, 11));
    assert_eq!(map.data.len(), want.len());
    let worst = map
        .data
        .iter()
        .zip(&want)
        .map(|(r, w)| (r - w).abs())
        .fold(0.0, f64::max);
    println!("worst per-pixel difference {worst:e}");
    assert!(worst < 1e-12, "worst per-pixel difference {worst:e}");
    // The map varies, so agreeing everywhere is not a coincidence of a flat map.
    let (lo, hi) = map
        .data
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    assert!(hi - lo > 0.03, "map spans {lo}..{hi}");
    assert_eq!(map.interior_mean(), ssim(&a, &b));
    let mut broken = map.clone();
    broken.data.pop();
    assert!(matches!(
        broken.interior_mean(),
        Err(MetricError::BadLength { input: "map", .. })
    ));
    let small = model::metrics::SsimMap {
        width: 3,
        height: 20,
        data: vec![1.0; 60],
    };
    assert!(matches!(
        small.interior_mean(),
        Err(MetricError::TooSmall { .. })
    ));
}

fn depth_from_json(v: &Value) -> DepthMap {
    let rows = v.as_array().expect("rows");
    let data: Vec<f32> = rows
        .iter()
        .flat_map(|row| row.as_array().expect("row").iter())
        .map(|x| match x {
            Value::String(s) => s.parse::<f32>().expect("nan or inf"),
            other => other.as_f64().expect("number") as f32,
        })
        .collect();
    let height = rows.len() as u32;
    DepthMap {
        width: data.len() as u32 / height,
        height,
        data,
    }
}

#[test]
fn depth_errors_match_numpy_fixture() {
    let reference = reference();
    let d = &reference["depth"];
    let pred = depth_from_json(&d["pred"]);
    let gt = depth_from_json(&d["gt"]);
    assert_eq!((gt.width, gt.height), (8, 6));
    let filter = DepthFilter {
        min_depth: num(d, "min_depth") as f32,
        max_depth: num(d, "max_depth") as f32,
    };
    assert_eq!(filter, DepthFilter::default());
    let e = depth_errors(&pred, &gt, &filter).expect("errors");
    assert_eq!(e.valid, d["valid"].as_u64().expect("valid") as usize);
    assert_eq!(e.missing, d["missing"].as_u64().expect("missing") as usize);
    assert_eq!(e.missing, 4);
    for (got, key) in [
        (e.abs_rel, "abs_rel"),
        (e.sq_rel, "sq_rel"),
        (e.rmse, "rmse"),
    ] {
        let want = num(d, key);
        assert!(
            ((got - want) / want).abs() < 1e-12,
            "{key}: {got} vs {want}"
        );
    }
}

#[test]
fn psnr_of_images_differing_by_a_tenth_is_20_db() {
    let a = textured(40, 30, 7);
    let mut b = a.clone();
    for (i, v) in b.data.iter_mut().enumerate() {
        // Up where there is room, down elsewhere: |a - b| = 0.1 everywhere.
        *v += if *v < 0.5 || i % 2 == 0 && *v < 0.9 {
            0.1
        } else {
            -0.1
        };
    }
    let p = psnr(&a, &b).expect("psnr");
    // 0.1 is not exact in f32; the rounding moves the result by well under 1e-5 dB.
    assert!((p - 20.0).abs() < 1e-5, "{p}");
    assert_eq!(psnr(&a, &a), Ok(f64::INFINITY));
}

#[test]
fn ssim_of_identical_images_is_one_and_noise_lowers_it_symmetrically() {
    let a = textured(64, 40, 3);
    assert!((ssim(&a, &a).expect("ssim") - 1.0).abs() < 1e-12);
    let b = textured(64, 40, 99);
    let ab = ssim(&a, &b).expect("ssim");
    let ba = ssim(&b, &a).expect("ssim");
    assert!(ab < 0.9, "{ab}");
    assert!((ab - ba).abs() < 1e-12);
}

/// Constant images have zero variance, so SSIM reduces to the luminance term
/// `(2ab + C1) / (a^2 + b^2 + C1)` with `C1 = 0.01^2`.
#[test]
fn ssim_of_constant_images_follows_the_closed_form() {
    for (x, y) in [(0.2f32, 0.9f32), (0.5, 0.5), (0.0, 1.0), (0.75, 0.25)] {
        let got = ssim(&constant(23, 17, x), &constant(23, 17, y)).expect("ssim");
        let (a, b, c1) = (x as f64, y as f64, 1e-4);
        let want = (2.0 * a * b + c1) / (a * a + b * b + c1);
        assert!((got - want).abs() < 1e-9, "{x} {y}: {got} vs {want}");
    }
    // Black against white: only C1 keeps it above zero.
    let bw = ssim(&constant(11, 11, 0.0), &constant(11, 11, 1.0)).expect("ssim");
    assert!((bw - 1e-4 / 1.0001).abs() < 1e-12, "{bw}");
}

#[test]
fn bad_input_gives_typed_errors() {
    let a = textured(20, 12, 1);
    let b = textured(12, 20, 1);
    let mismatch = MetricError::SizeMismatch {
        a_width: 20,
        a_height: 12,
        b_width: 12,
        b_height: 20,
    };
    assert_eq!(psnr(&a, &b), Err(mismatch.clone()));
    assert_eq!(ssim(&a, &b), Err(mismatch.clone()));
    assert_eq!(error_map(&a, &b), Err(mismatch));

    let mut nan = a.clone();
    nan.data[3 * (2 * 20 + 7) + 1] = f32::NAN;
    let at = MetricError::NonFinite {
        input: "b",
        x: 7,
        y: 2,
    };
    assert_eq!(psnr(&a, &nan), Err(at.clone()));
    assert_eq!(ssim(&a, &nan), Err(at.clone()));
    assert_eq!(error_map(&a, &nan), Err(at));
    let mut inf = a.clone();
    inf.data[0] = f32::INFINITY;
    assert!(matches!(
        psnr(&inf, &a),
        Err(MetricError::NonFinite {
            input: "a",
            x: 0,
            y: 0
        })
    ));

    let small = textured(10, 30, 1);
    assert_eq!(
        ssim(&small, &small),
        Err(MetricError::TooSmall {
            width: 10,
            height: 30,
            window: SSIM_WINDOW
        })
    );
    let mut short = a.clone();
    short.data.pop();
    assert_eq!(
        psnr(&a, &short),
        Err(MetricError::BadLength {
            input: "b",
            expected: 720,
            actual: 719
        })
    );
    let empty = RgbImage::new(0, 0);
    assert_eq!(psnr(&empty, &empty), Err(MetricError::Empty));
}

#[test]
fn error_map_is_the_mean_absolute_channel_error() {
    let a = RgbImage {
        width: 2,
        height: 1,
        data: vec![0.0, 0.5, 1.0, 0.25, 0.25, 0.25],
    };
    let b = RgbImage {
        width: 2,
        height: 1,
        data: vec![0.5, 0.5, 0.25, 0.25, 1.0, 0.0],
    };
    // (0.5 + 0 + 0.75) / 3 and (0 + 0.75 + 0.25) / 3.
    let map = error_map(&a, &b).expect("map");
    assert_eq!(map.len(), 2);
    assert!((map[0] - 1.25 / 3.0).abs() < 1e-7);
    assert!((map[1] - 1.0 / 3.0).abs() < 1e-7);
}

fn depth(data: &[f32]) -> DepthMap {
    DepthMap {
        width: data.len() as u32,
        height: 1,
        data: data.to_vec(),
    }
}

#[test]
fn depth_errors_on_three_pixels_by_hand() {
    // |p - g| / g = 0.5, 0, 0.5; (p - g)^2 / g = 0.5, 0, 2.5; (p - g)^2 = 1, 0, 25.
    let e = depth_errors(
        &depth(&[3.0, 4.0, 5.0]),
        &depth(&[2.0, 4.0, 10.0]),
        &DepthFilter::default(),
    )
    .expect("errors");
    assert!((e.abs_rel - 1.0 / 3.0).abs() < 1e-12);
    assert!((e.sq_rel - 1.0).abs() < 1e-12);
    assert!((e.rmse - (26.0f64 / 3.0).sqrt()).abs() < 1e-12);
    assert_eq!((e.valid, e.missing), (3, 0));
}

#[test]
fn depth_filter_excludes_unusable_ground_truth() {
    let filter = DepthFilter::default();
    assert_eq!((filter.min_depth, filter.max_depth), (1e-3, 80.0));
    // Only the last ground truth (5 m) is usable: 0, negative, NaN, beyond 80 m, inf and
    // below min_depth are all excluded.
    let gt = depth(&[0.0, -2.0, f32::NAN, 80.5, f32::INFINITY, 1e-4, 5.0]);
    let pred = depth(&[1.0; 7]);
    let e = depth_errors(&pred, &gt, &filter).expect("errors");
    assert_eq!((e.valid, e.missing), (1, 0));
    assert!((e.abs_rel - 0.8).abs() < 1e-12);
    assert!((e.rmse - 4.0).abs() < 1e-12);

    let none = depth(&[0.0, f32::NAN, 100.0]);
    assert_eq!(
        depth_errors(&pred_of(3), &none, &filter),
        Err(MetricError::NoValidPixels)
    );
}

fn pred_of(n: usize) -> DepthMap {
    depth(&vec![1.0; n])
}

/// Holes (0, NaN, negative, -inf) score as min_depth, +inf and far values as max_depth,
/// and holes are counted.
#[test]
fn missing_and_out_of_range_predictions_are_clamped_and_counted() {
    let filter = DepthFilter {
        min_depth: 0.5,
        max_depth: 20.0,
    };
    let gt = depth(&[4.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0]);
    let pred = depth(&[
        0.0,
        f32::NAN,
        -3.0,
        f32::NEG_INFINITY,
        f32::INFINITY,
        30.0,
        0.1,
    ]);
    let e = depth_errors(&pred, &gt, &filter).expect("errors");
    assert_eq!((e.valid, e.missing), (7, 5));
    // Effective predictions: 0.5 x4, 20 x2, 0.5 (0.1 is a real prediction, clamped).
    let want_abs = (5.0 * 3.5 / 4.0 + 2.0 * 16.0 / 4.0) / 7.0;
    let want_sq = (5.0 * 12.25 + 2.0 * 256.0) / 7.0;
    assert!((e.abs_rel - want_abs).abs() < 1e-12, "{}", e.abs_rel);
    assert!((e.sq_rel - want_sq / 4.0).abs() < 1e-12);
    assert!((e.rmse - want_sq.sqrt()).abs() < 1e-12);
}

#[test]
fn depth_errors_reject_bad_filters_and_sizes() {
    let gt = depth(&[4.0, 5.0]);
    for (lo, hi) in [
        (0.0, 80.0),
        (10.0, 5.0),
        (1.0, f32::INFINITY),
        (f32::NAN, 80.0),
    ] {
        let filter = DepthFilter {
            min_depth: lo,
            max_depth: hi,
        };
        assert!(matches!(
            depth_errors(&gt, &gt, &filter),
            Err(MetricError::InvalidFilter { .. })
        ));
    }
    assert!(matches!(
        depth_errors(&depth(&[1.0; 3]), &gt, &DepthFilter::default()),
        Err(MetricError::SizeMismatch { .. })
    ));
    let broken = DepthMap {
        width: 3,
        height: 1,
        data: vec![1.0; 2],
    };
    assert_eq!(
        depth_errors(&broken, &broken, &DepthFilter::default()),
        Err(MetricError::BadLength {
            input: "pred",
            expected: 3,
            actual: 2
        })
    );
}
