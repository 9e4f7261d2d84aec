//! PNG output: exact bytes for known inputs, clamping of odd values, the colour map's shape,
//! and files that read back with the `image` crate.

use renderer::picture::{
    alpha_to_gray8, auto_depth_range, confidence_to_gray8, depth_to_rgb8, save_alpha_png,
    save_confidence_png, save_depth_png, save_rgb_png, to_rgb8, viridis, DepthScale, PictureError,
};
use renderer::RenderOutput;

/// A `w x h` output with the given depths, alpha 1 and a colour ramp.
fn with_depths(w: u32, h: u32, depth: &[f32]) -> RenderOutput {
    let mut out = RenderOutput::zeros(w, h);
    out.depth = depth.to_vec();
    out.alpha = vec![1.0; depth.len()];
    out.rgb = (0..3 * depth.len())
        .map(|i| i as f32 / (3 * depth.len()) as f32)
        .collect();
    out.confidence = (0..depth.len())
        .map(|i| i as f32 / depth.len() as f32)
        .collect();
    out
}

#[test]
fn a_known_2x2_colour_image_maps_to_known_bytes() {
    let mut out = RenderOutput::zeros(2, 2);
    out.rgb = vec![
        0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.5, 0.25, 0.1, 0.002, 0.998, 0.5,
    ];
    let want = [0, 0, 0, 255, 255, 255, 128, 64, 26, 1, 254, 128];
    assert_eq!(to_rgb8(&out).unwrap(), want);
}

#[test]
fn odd_values_clamp_as_documented() {
    let mut out = RenderOutput::zeros(2, 1);
    let odd = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.5, 1.5, 2e30];
    out.rgb = odd.to_vec();
    assert_eq!(to_rgb8(&out).unwrap(), [0, 255, 0, 0, 255, 255]);
    out.alpha = vec![f32::NAN, 7.0];
    out.confidence = vec![-1.0, 0.5];
    assert_eq!(alpha_to_gray8(&out).unwrap(), [0, 255]);
    assert_eq!(confidence_to_gray8(&out).unwrap(), [0, 128]);
}

#[test]
fn mismatched_lengths_are_typed_errors() {
    let mut out = RenderOutput::zeros(2, 2);
    out.rgb.pop();
    match to_rgb8(&out) {
        Err(PictureError::SizeMismatch {
            channel: "rgb",
            expected: 12,
            got: 11,
        }) => {}
        other => panic!("{other:?}"),
    }
    let mut out = RenderOutput::zeros(2, 2);
    out.alpha.push(1.0);
    assert!(matches!(
        depth_to_rgb8(&out, DepthScale::Auto),
        Err(PictureError::SizeMismatch {
            channel: "alpha",
            ..
        })
    ));
    out.alpha.pop();
    out.depth.clear();
    let fixed = DepthScale::Range { min: 1.0, max: 2.0 };
    assert!(matches!(
        depth_to_rgb8(&out, fixed),
        Err(PictureError::SizeMismatch {
            channel: "depth",
            ..
        })
    ));
}

#[test]
fn a_fixed_depth_range_maps_near_bright_and_far_dark() {
    let out = with_depths(2, 2, &[1.0, 2.0, 3.0, 5.0]);
    let got = depth_to_rgb8(&out, DepthScale::Range { min: 1.0, max: 3.0 }).unwrap();
    let want: Vec<u8> = [viridis(1.0), viridis(0.5), viridis(0.0), viridis(0.0)].concat();
    assert_eq!(got, want, "far beyond the range clamps to the far colour");
    assert_eq!(viridis(1.0), [253, 231, 37], "near is yellow");
    assert_eq!(viridis(0.0), [68, 1, 84], "far is dark purple");
}

#[test]
fn invalid_depths_are_black() {
    let mut out = with_depths(3, 2, &[2.0, f32::NAN, -1.0, f32::INFINITY, 0.0, 2.0]);
    out.alpha[5] = 1e-4;
    out.alpha[0] = f32::NAN;
    let got = depth_to_rgb8(&out, DepthScale::Range { min: 1.0, max: 3.0 }).unwrap();
    assert_eq!(got, vec![0; 18]);
    assert_eq!(auto_depth_range(&out).unwrap(), None);
    assert_eq!(depth_to_rgb8(&out, DepthScale::Auto).unwrap(), vec![0; 18]);
}

#[test]
fn the_auto_range_is_the_2nd_to_98th_percentile() {
    let depths: Vec<f32> = (1..=100).map(|d| d as f32).collect();
    let mut out = with_depths(10, 10, &depths);
    // An invalid pixel does not count: the 99 valid depths 2..=100 remain.
    out.alpha[0] = 0.0;
    assert_eq!(auto_depth_range(&out).unwrap(), Some((4.0, 98.0)));
    let got = depth_to_rgb8(&out, DepthScale::Auto).unwrap();
    let px = |i: usize| [got[3 * i], got[3 * i + 1], got[3 * i + 2]];
    assert_eq!(px(0), [0, 0, 0]);
    assert_eq!(
        px(1),
        viridis(1.0),
        "below the 2nd percentile: clamped near"
    );
    assert_eq!(px(3), viridis(1.0));
    assert_eq!(px(97), viridis(0.0));
    assert_eq!(
        px(99),
        viridis(0.0),
        "beyond the 98th percentile: clamped far"
    );
    assert_eq!(px(50), viridis((98.0 - 51.0) / 94.0));
    // One depth everywhere: the middle colour.
    let flat = with_depths(2, 1, &[7.0, 7.0]);
    let want = [viridis(0.5), viridis(0.5)].concat();
    assert_eq!(depth_to_rgb8(&flat, DepthScale::Auto).unwrap(), want);
}

#[test]
fn bad_fixed_ranges_are_refused() {
    let out = with_depths(1, 1, &[1.0]);
    for (min, max) in [
        (2.0, 2.0),
        (3.0, 1.0),
        (f32::NAN, 1.0),
        (0.0, f32::INFINITY),
    ] {
        let err = depth_to_rgb8(&out, DepthScale::Range { min, max }).unwrap_err();
        assert!(matches!(err, PictureError::BadRange { .. }), "{min} {max}");
    }
}

#[test]
fn the_colour_map_brightens_monotonically() {
    let luma = |c: [u8; 3]| 0.2126 * c[0] as f32 + 0.7152 * c[1] as f32 + 0.0722 * c[2] as f32;
    // Steps of 1/64 rise by at least 2 in 8-bit luminance, more than rounding can undo.
    let samples: Vec<f32> = (0..=64).map(|k| luma(viridis(k as f32 / 64.0))).collect();
    for (k, w) in samples.windows(2).enumerate() {
        assert!(w[1] > w[0], "luminance falls at step {k}: {w:?}");
    }
    assert_eq!(viridis(-3.0), viridis(0.0));
    assert_eq!(viridis(7.0), viridis(1.0));
    assert_eq!(viridis(f32::NAN), [0, 0, 0]);
}

#[test]
fn written_pngs_read_back_with_the_same_pixels() {
    let depths: Vec<f32> = (0..35).map(|d| 1.0 + d as f32 * 0.5).collect();
    let mut out = with_depths(7, 5, &depths);
    out.alpha[3] = 0.25;
    let dir = std::env::temp_dir().join(format!("renderer-picture-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (rgb, depth, alpha, conf) = (
        dir.join("rgb.png"),
        dir.join("depth.png"),
        dir.join("alpha.png"),
        dir.join("conf.png"),
    );
    save_rgb_png(&out, &rgb).unwrap();
    save_depth_png(&out, &depth, DepthScale::Auto).unwrap();
    save_alpha_png(&out, &alpha).unwrap();
    save_confidence_png(&out, &conf).unwrap();
    let read = |p: &std::path::Path| image::open(p).unwrap();
    let (r, d, a, c) = (read(&rgb), read(&depth), read(&alpha), read(&conf));
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!((r.width(), r.height()), (7, 5));
    assert_eq!(r.to_rgb8().into_raw(), to_rgb8(&out).unwrap());
    let want_depth = depth_to_rgb8(&out, DepthScale::Auto).unwrap();
    assert_eq!(d.to_rgb8().into_raw(), want_depth);
    assert_eq!(a.to_luma8().into_raw(), alpha_to_gray8(&out).unwrap());
    assert_eq!(c.to_luma8().into_raw(), confidence_to_gray8(&out).unwrap());
}

#[test]
fn encoder_failures_are_typed_errors() {
    let out = with_depths(2, 1, &[1.0, 2.0]);
    let err = save_rgb_png(&out, "/nonexistent/dir/x.png").unwrap_err();
    assert!(matches!(err, PictureError::Encode(_)), "{err:?}");
    let empty = RenderOutput::zeros(0, 0);
    assert_eq!(to_rgb8(&empty).unwrap(), Vec::<u8>::new());
    let path = std::env::temp_dir().join(format!("renderer-empty-{}.png", std::process::id()));
    let saved = save_rgb_png(&empty, &path);
    let _ = std::fs::remove_file(&path);
    assert!(matches!(saved, Err(PictureError::Encode(_))), "{saved:?}");
}
