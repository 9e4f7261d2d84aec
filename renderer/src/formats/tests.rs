//! Round trips through each format with each format's stated tolerance, and the extremes:
//! empty and one-Gaussian maps, 2 M Gaussians, non-finite fields, colours outside [0, 1],
//! positions 1e5 m out.

use glam::{Quat, Vec3};

use super::*;
use crate::ply::SH_C0;
use crate::{scene, Gaussian, Intrinsics};

fn street(n: usize) -> GaussianSet {
    let mut set = scene::random_in_view(7, n, &Intrinsics::from_hfov(256, 64, 90.0));
    // Rotations of every kind, not only what the generator makes.
    for (i, q) in set.rotations.iter_mut().enumerate() {
        let axis = Vec3::new(1.0, (i % 7) as f32 - 3.0, 0.5).normalize();
        *q = Quat::from_axis_angle(axis, i as f32 * 0.37 - 2.0);
    }
    set
}

fn bytes(set: &GaussianSet, format: MapFormat) -> (Exported, Vec<u8>) {
    let mut out = Vec::new();
    let e = write_map(set, format, &mut out).unwrap();
    (e, out)
}

/// The largest difference of each field between `a` and `b`: position, log-scale, rotation
/// (1 - |dot|, so q and -q agree), opacity, colour.
fn max_errors(a: &GaussianSet, b: &GaussianSet) -> [f32; 5] {
    assert_eq!(a.len(), b.len());
    let mut e = [0.0f32; 5];
    for i in 0..a.len() {
        let (x, y) = (a.get(i), b.get(i));
        let d = [
            (x.mean - y.mean).abs().max_element(),
            (x.log_scale - y.log_scale).abs().max_element(),
            1.0 - unit_rotation(x.rotation).dot(y.rotation).abs(),
            (x.opacity - y.opacity).abs(),
            (x.color - y.color).abs().max_element(),
        ];
        for (m, v) in e.iter_mut().zip(d) {
            *m = m.max(v);
        }
    }
    e
}

#[test]
fn every_format_round_trips_within_its_stated_precision() {
    let set = street(5_000);
    for format in MapFormat::ALL {
        let (e, data) = bytes(&set, format);
        assert_eq!((e.gaussians, e.skipped_non_finite), (set.len(), 0));
        let (seen, back) = read_map(data.as_slice()).unwrap();
        assert_eq!(seen, format);
        let [p, s, q, a, c] = max_errors(&set, &back);
        match format {
            // Float32 throughout; colours through f_dc in f32.
            MapFormat::Ply | MapFormat::Glb => {
                assert_eq!(p, 0.0, "{format}");
                assert!(
                    s < 1e-5 && q < 1e-6 && a < 1e-6 && c < 1e-6,
                    "{format}: {s} {q} {a} {c}"
                );
            }
            MapFormat::Spz => {
                // Positions: half a step of 12 fractional bits. Log-scales: half of 1/16.
                // Rotations: 9-bit magnitudes, 1 - |dot| within 5e-6. Opacity: half of 1/255.
                // Colour: half a step of SH_C0 / (0.15 * 255) = 0.0074.
                assert!(p <= 0.5 / 4096.0 + 1e-6, "position {p}");
                assert!(s <= 0.5 / 16.0 + 1e-6, "log-scale {s}");
                assert!(q < 5e-6, "rotation {q}");
                assert!(a <= 0.5 / 255.0 + 1e-6, "opacity {a}");
                let colour_step = (SH_C0 / (spz::COLOR_SCALE * 255.0)) as f32;
                assert!(
                    c <= colour_step / 2.0 + 1e-6,
                    "colour {c} vs step {colour_step}"
                );
                assert_eq!(e.max_position_error_m, 0.5 / 4096.0);
            }
        }
    }
}

#[test]
fn the_format_is_told_by_content_not_name() {
    let set = street(10);
    let dir = std::env::temp_dir().join(format!("ss-formats-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for format in MapFormat::ALL {
        // Every format saved under a misleading name still loads as itself.
        let path = dir.join("map.ply.bin");
        save_map(&set, &path, format).unwrap();
        let (seen, back) = load_map(&path).unwrap();
        assert_eq!((seen, back.len()), (format, 10));
    }
    std::fs::write(dir.join("x"), b"\x00\x01junk").unwrap();
    assert!(matches!(
        load_map(dir.join("x")),
        Err(MapFileError::UnknownFormat(h)) if h == [0, 1, b'j', b'u']
    ));
    assert!(matches!(
        read_map(&b""[..]),
        Err(MapFileError::UnknownFormat(_))
    ));
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!("SPZ".parse::<MapFormat>(), Ok(MapFormat::Spz));
    assert!("obj".parse::<MapFormat>().is_err());
}

#[test]
fn empty_and_one_gaussian_maps_round_trip() {
    let one = street(1);
    for format in MapFormat::ALL {
        for set in [GaussianSet::default(), one.clone()] {
            let (e, data) = bytes(&set, format);
            assert_eq!(e.gaussians, set.len());
            let (_, back) = read_map(data.as_slice()).unwrap();
            assert_eq!(back.len(), set.len(), "{format}");
        }
    }
}

#[test]
fn non_finite_gaussians_are_skipped_and_counted_and_colours_clamped() {
    let mut set = street(6);
    set.means[0].x = f32::NAN;
    set.log_scales[1].y = f32::INFINITY;
    set.log_scales[2].z = 200.0; // exp overflows f32
    set.rotations[3] = Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0);
    set.colors[4] = Vec3::new(-0.5, 1.5, 0.25);
    set.opacities[5] = 1.25;
    for format in MapFormat::ALL {
        let (e, data) = bytes(&set, format);
        assert_eq!(
            (e.gaussians, e.skipped_non_finite, e.clamped),
            (2, 4, 2),
            "{format}"
        );
        let (_, back) = read_map(data.as_slice()).unwrap();
        assert_eq!(back.len(), 2);
        assert!(back.means.iter().all(|m| m.is_finite()));
        let c = back.colors[0];
        assert!(
            c.x.abs() < 0.004 && (c.y - 1.0).abs() < 0.004,
            "{format}: {c}"
        );
        assert!((back.opacities[1] - 1.0).abs() < 0.002, "{format}");
    }
    // The raw writers refuse what sanitise would skip.
    let mut bad = street(2);
    bad.opacities[1] = f32::NAN;
    assert!(matches!(
        spz::write_spz(&bad, Vec::new()),
        Err(spz::SpzError::NonFinite {
            index: 1,
            what: "opacity"
        })
    ));
    assert!(matches!(
        glb::write_glb(&bad, Vec::new()),
        Err(glb::GlbError::NonFinite {
            index: 1,
            what: "opacity"
        })
    ));
}

#[test]
fn positions_1e5_m_out_keep_the_stated_precision() {
    // A map reaching 1e5 m from its frame's origin. Float32 itself resolves 7.8 mm there
    // (PLY and glTF copy the f32 means exactly); SPZ drops to 6 fractional bits, so its
    // error is at most half of 1/64 m = 7.8 mm.
    let mut set = street(200);
    for (i, m) in set.means.iter_mut().enumerate() {
        *m += Vec3::new(1e5, -3e4, 5e4) * (i as f32 / 199.0);
    }
    for format in MapFormat::ALL {
        let (e, data) = bytes(&set, format);
        let (_, back) = read_map(data.as_slice()).unwrap();
        let [p, ..] = max_errors(&set, &back);
        match format {
            MapFormat::Spz => {
                assert_eq!(e.max_position_error_m, 0.5 / 64.0);
                assert!(p as f64 <= 0.5 / 64.0, "SPZ position error {p} m at 1e5 m");
                assert!(p > 0.0);
            }
            _ => assert_eq!(p, 0.0, "{format}"),
        }
    }
    // Beyond 24 bits of whole metres SPZ refuses rather than wrap around.
    let mut too_far = street(1);
    too_far.means[0] = Vec3::new(0.0, 9e6, 0.0);
    let err = write_map(&too_far, MapFormat::Spz, Vec::new()).unwrap_err();
    assert!(
        matches!(&err, MapFileError::Spz(spz::SpzError::TooFar { max_abs_m }) if *max_abs_m == 9e6),
        "{err}"
    );
}

#[test]
fn two_million_gaussians_round_trip() {
    let n = 2_000_000;
    let mut set = GaussianSet::with_capacity(n);
    for i in 0..n {
        let f = i as f32;
        set.push(Gaussian {
            mean: Vec3::new(
                (f * 0.618).fract() * 100.0 - 50.0,
                (f * 0.414).fract() * 10.0,
                f * 1e-4,
            ),
            log_scale: Vec3::splat(-3.0 + (i % 5) as f32 * 0.1),
            rotation: Quat::from_rotation_y(f * 1e-3),
            opacity: (i % 251) as f32 / 250.0,
            color: Vec3::new((i % 256) as f32 / 255.0, 0.5, 1.0 - (i % 17) as f32 / 16.0),
            confidence: 1.0,
        });
    }
    for format in [MapFormat::Spz, MapFormat::Glb] {
        let (e, data) = bytes(&set, format);
        assert_eq!(e.gaussians, n);
        let (_, back) = read_map(data.as_slice()).unwrap();
        assert_eq!(back.len(), n);
        let last = back.get(n - 1);
        assert!(
            (last.mean - set.means[n - 1]).abs().max_element() < 1e-3,
            "{format}"
        );
        if format == MapFormat::Spz {
            // About 6 bytes per Gaussian once gzipped, against PLY's 72.
            assert!(data.len() < n * 14, "{} bytes", data.len());
        }
    }
}
