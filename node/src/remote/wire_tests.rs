use glam::{DQuat, Quat};
use model::consistency::{CheckReport, Verdict};
use renderer::GaussianSet;

use super::*;

fn fingerprint() -> Fingerprint {
    Fingerprint {
        method: "stereosplat".into(),
        preset: "tiny".into(),
        settings: vec!["gaussian_stride=2".into()],
        weights_sha256: "ab".repeat(32),
    }
}

/// A frame whose left image holds 8-bit values and whose right one does not.
fn job() -> BinJob {
    let mut right = RgbImage::new(3, 2);
    right.data[4] = 0.123_456_79;
    right.data[5] = f32::MIN_POSITIVE;
    BinJob {
        bin_id: u64::MAX - 1,
        attempt: 2,
        fingerprint: fingerprint(),
        on_check_fail: OnCheckFail::LowerOpacity,
        render: true,
        frame: StereoFrame {
            index: 17,
            left: RgbImage::from_rgb8(
                3,
                2,
                &[
                    0, 1, 2, 127, 128, 254, 255, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19,
                ],
            ),
            right,
            left_to_world: DAffine3::from_rotation_translation(
                DQuat::from_rotation_z(0.3),
                DVec3::new(4.0e5, -1.0e-9, 3.0),
            ),
        },
        rig: StereoRig {
            intrinsics: Intrinsics::from_hfov(3, 2, 80.0),
            baseline: 0.6,
        },
        stamps: Stamps {
            source_ns: i64::MIN,
            arrival_ns: 1,
            opened_ns: i64::MAX,
            ..Stamps::default()
        },
    }
}

#[test]
fn a_bin_request_decodes_to_the_same_frame_bit_for_bit() {
    let sent = job();
    let bytes = Request::Bin(Box::new(sent.clone())).encode();
    let Request::Bin(got) = Request::decode(&bytes).unwrap() else {
        panic!("a bin")
    };
    assert_eq!((got.bin_id, got.attempt), (sent.bin_id, sent.attempt));
    assert_eq!(got.fingerprint, sent.fingerprint);
    assert_eq!(got.on_check_fail, OnCheckFail::LowerOpacity);
    assert!(got.render);
    assert_eq!(got.frame.index, 17);
    let bits = |i: &RgbImage| i.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&got.frame.left), bits(&sent.frame.left));
    assert_eq!(bits(&got.frame.right), bits(&sent.frame.right));
    assert_eq!(got.frame.left_to_world, sent.frame.left_to_world);
    assert_eq!(got.rig, sent.rig);
    assert_eq!(got.stamps, sent.stamps);
}

#[test]
fn an_image_of_bytes_travels_as_bytes_and_others_as_floats() {
    let mut left = CdrWriter::new();
    write_image(&mut left, &job().frame.left);
    let mut right = CdrWriter::new();
    write_image(&mut right, &job().frame.right);
    // Header, size (8), kind (1), padding to 4, length (4), then 18 bytes or 72.
    assert_eq!(left.into_bytes().len(), 4 + 8 + 4 + 4 + 18);
    assert_eq!(right.into_bytes().len(), 4 + 8 + 4 + 4 + 72);
}

fn map_reply() -> Output {
    let mut set = GaussianSet::with_capacity(2);
    for (i, v) in [1.5e-7f32, -3.0e8].into_iter().enumerate() {
        set.means.push(Vec3::new(v, f32::MAX, -0.0));
        set.log_scales.push(Vec3::splat(-20.0 + i as f32));
        set.rotations.push(Quat::from_rotation_y(v));
        set.opacities.push(0.999_999_9);
        set.colors.push(Vec3::new(0.1, 0.2, 0.3));
        set.confidences.push(f32::EPSILON);
    }
    let report = CheckReport {
        score: 0.25,
        coverage: 1.0,
        samples: 9,
        textured: 12,
        verdict: Verdict::Fail,
    };
    Output {
        bin_id: 3,
        bin_to_world: DAffine3::from_translation(DVec3::new(1.0e6, 2.0, 3.0)),
        result: Ok(set),
        check: CheckOutcome {
            primary: Some(report),
            action: CheckAction::Sgm,
            fallback: Some(CheckReport {
                verdict: Verdict::Pass,
                ..report
            }),
        },
        render_follows: true,
        stamps: Stamps {
            model_end_ns: 42,
            stage_end_ns: [1, 2, 3, 4, 5],
            ..Stamps::default()
        },
        queue_depth: 0,
        point: 0,
    }
}

#[test]
fn a_map_reply_decodes_to_the_same_gaussians_bit_for_bit() {
    let sent = map_reply();
    let bytes = Reply::Map(2, Box::new(map_reply())).encode();
    let Reply::Map(2, got) = Reply::decode(&bytes).unwrap() else {
        panic!("a map of attempt 2")
    };
    let (a, b) = (got.result.as_ref().unwrap(), sent.result.as_ref().unwrap());
    assert_eq!(a.means, b.means);
    assert_eq!(a.log_scales, b.log_scales);
    assert_eq!(a.rotations, b.rotations);
    assert_eq!(a.opacities, b.opacities);
    assert_eq!(a.colors, b.colors);
    assert_eq!(a.confidences, b.confidences);
    assert_eq!(got.check, sent.check);
    assert_eq!(got.stamps, sent.stamps);
    assert_eq!(got.bin_to_world, sent.bin_to_world);
    assert!(got.render_follows);
}

#[test]
fn errors_travel_as_their_words() {
    let mut out = map_reply();
    out.result = Err("reconstructor panicked: boom".into());
    let bytes = Reply::Map(0, Box::new(out)).encode();
    let Reply::Map(0, got) = Reply::decode(&bytes).unwrap() else {
        panic!("a map")
    };
    assert_eq!(got.result.unwrap_err(), "reconstructor panicked: boom");
    let render = Reply::Render(Rendered {
        bin_id: 9,
        image: Err("no adapter".into()),
        render_end_ns: -1,
    });
    let Reply::Render(r) = Reply::decode(&render.encode()).unwrap() else {
        panic!("a render")
    };
    assert_eq!(
        (r.bin_id, r.image.unwrap_err().as_str(), r.render_end_ns),
        (9, "no adapter", -1)
    );
}

#[test]
fn every_cut_and_every_flipped_byte_of_a_request_or_reply_is_an_error_or_a_value_never_a_panic() {
    let payloads = [
        Request::Bin(Box::new(job())).encode(),
        Request::Hello(fingerprint()).encode(),
        Reply::Map(1, Box::new(map_reply())).encode(),
        Reply::Hello(Hello {
            fingerprint: fingerprint(),
            threads: 1,
        })
        .encode(),
    ];
    for bytes in &payloads {
        for cut in 0..bytes.len() {
            let _ = Request::decode(&bytes[..cut]);
            let _ = Reply::decode(&bytes[..cut]);
        }
        for at in 0..bytes.len() {
            let mut bad = bytes.clone();
            bad[at] ^= 0xff;
            let _ = Request::decode(&bad);
            let _ = Reply::decode(&bad);
        }
    }
    // A cut map is an error, not a shorter map.
    let whole = &payloads[2];
    assert!(Reply::decode(&whole[..whole.len() - 1]).is_err());
}

#[test]
fn another_protocol_version_is_refused_by_name() {
    let mut bytes = Request::Hello(fingerprint()).encode();
    bytes[4] = 9;
    let e = Request::decode(&bytes).unwrap_err().to_string();
    assert_eq!(e, "`version`: protocol 9; this build speaks 1");
}

/// An image header claiming `width` x `height` of `kind`, then an empty byte sequence.
fn image_header(width: u32, height: u32, kind: u8) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.u32(width);
    w.u32(height);
    w.u8(kind);
    w.bytes(&[]);
    w.into_bytes()
}

#[test]
fn image_sizes_at_the_u32_extremes_are_errors_not_wrapped_products() {
    // 3 x u32::MAX x u32::MAX does not fit 64 bits: without checked arithmetic it wraps in
    // release builds (and panics in debug ones).
    for kind in [IMAGE_BYTES, IMAGE_FLOATS] {
        let bytes = image_header(u32::MAX, u32::MAX, kind);
        let e = read_image(&mut CdrReader::new(&bytes).unwrap()).unwrap_err();
        assert!(e.to_string().contains("does not fit 64 bits"), "{e}");
    }
    // u32::MAX x 1 fits; its floats do too (4 x 3 x u32::MAX), and an empty sequence is not
    // that many.
    let bytes = image_header(u32::MAX, 1, IMAGE_FLOATS);
    let e = read_image(&mut CdrReader::new(&bytes).unwrap()).unwrap_err();
    assert!(
        e.to_string().contains("0 bytes for 12884901885 floats"),
        "{e}"
    );
    // More floats than 64 bits can count in bytes.
    let mut w = CdrWriter::new();
    w.bytes(&[]);
    let bytes = w.into_bytes();
    let e = read_f32s(&mut CdrReader::new(&bytes).unwrap(), "floats", u64::MAX / 2).unwrap_err();
    assert!(e.to_string().contains("does not fit 64 bits"), "{e}");
    // A map claiming u32::MAX Gaussians with empty arrays is an error.
    let mut w = CdrWriter::new();
    w.u32(u32::MAX);
    w.bytes(&[]);
    let bytes = w.into_bytes();
    assert!(read_set(&mut CdrReader::new(&bytes).unwrap()).is_err());
}

#[test]
fn a_request_kind_is_read_from_its_first_bytes_alone() {
    let bin = Request::Bin(Box::new(job())).encode();
    let hello = Request::Hello(fingerprint()).encode();
    assert_eq!(
        Request::kind(&bin[..REQUEST_PREFIX]).unwrap(),
        RequestKind::Bin
    );
    assert_eq!(
        Request::kind(&hello[..REQUEST_PREFIX]).unwrap(),
        RequestKind::Hello
    );
    assert!(Request::kind(&bin[..REQUEST_PREFIX - 1]).is_err());
    let mut other = bin.clone();
    other[8] = 7;
    assert!(Request::kind(&other).is_err());
    // The job's own payload is the request's.
    assert_eq!(job().request(), bin);
}
