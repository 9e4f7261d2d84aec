//! PLY reader and writer: round trips, foreign files, every error case, and a seeded
//! fuzz-style check that no input makes the reader panic.

use glam::{Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::ply::{load_ply, read_ply, save_ply, write_ply, PlyError, SH_C0};
use renderer::scene::random_in_view;
use renderer::{Gaussian, GaussianSet, Intrinsics};

/// A seeded set plus the edge values: opacity 0 and 1, colour 0 and 1, a non-unit quaternion.
fn sample_set() -> GaussianSet {
    let mut set = random_in_view(11, 300, &Intrinsics::from_hfov(64, 48, 60.0));
    for (opacity, c) in [(0.0, 0.0), (1.0, 1.0), (0.5, 0.25)] {
        set.push(Gaussian {
            mean: Vec3::new(-1.5, 2.0, 1e4),
            log_scale: Vec3::new(-7.0, 0.0, 3.0),
            rotation: Quat::from_xyzw(0.1, -0.2, 0.3, 2.0),
            opacity,
            color: Vec3::splat(c),
            confidence: c,
        });
    }
    set
}

fn to_bytes(set: &GaussianSet) -> Vec<u8> {
    let mut bytes = Vec::new();
    write_ply(set, &mut bytes).unwrap();
    bytes
}

/// `|a - b| <= 1e-6 * max(|a|, |b|, 1)`: relative above 1, absolute below (colours near 0
/// pass through `f_dc = (c - 0.5) / C0`, stored in `f32`, whose error is absolute).
fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-6 * a.abs().max(b.abs()).max(1.0)
}

#[test]
fn a_random_set_round_trips() {
    let set = sample_set();
    let back = read_ply(to_bytes(&set).as_slice()).unwrap();
    assert_eq!(back.len(), set.len());
    // Stored as they are: exact.
    assert_eq!(back.means, set.means);
    assert_eq!(back.log_scales, set.log_scales);
    assert_eq!(back.rotations, set.rotations, "reordered, not normalised");
    assert_eq!(back.confidences, set.confidences);
    for i in 0..set.len() {
        let (a, b) = (set.get(i), back.get(i));
        for k in 0..3 {
            assert!(close(a.color[k], b.color[k]), "{i}: {a:?} vs {b:?}");
        }
        // Logit then sigmoid, relative 1e-6 once clamped to [1e-6, 1 - 1e-6].
        let want = a.opacity.clamp(1e-6, 1.0 - 1e-6);
        assert!(
            (want - b.opacity).abs() <= 1e-6 * want,
            "{i}: {want} vs {}",
            b.opacity
        );
    }
}

#[test]
fn save_and_load_agree_with_write_and_read() {
    let set = sample_set();
    let path = std::env::temp_dir().join(format!("renderer-ply-{}.ply", std::process::id()));
    save_ply(&set, &path).unwrap();
    let loaded = load_ply(&path);
    std::fs::remove_file(&path).unwrap();
    assert_eq!(
        loaded.unwrap(),
        read_ply(to_bytes(&set).as_slice()).unwrap()
    );
}

#[test]
fn the_written_layout_is_the_3dgs_one() {
    let mut set = GaussianSet::default();
    set.push(Gaussian {
        mean: Vec3::new(1.0, 2.0, 3.0),
        log_scale: Vec3::new(-1.0, -2.0, -3.0),
        rotation: Quat::from_xyzw(0.1, 0.2, 0.3, 0.9),
        opacity: 0.5,
        color: Vec3::new(0.5, 0.5 + SH_C0 as f32, 0.0),
        confidence: 0.25,
    });
    let bytes = to_bytes(&set);
    let body_at = body_start(&bytes);
    let header = std::str::from_utf8(&bytes[..body_at]).unwrap();
    let props: Vec<&str> = header
        .lines()
        .filter_map(|l| l.strip_prefix("property float "))
        .collect();
    let want = "x y z nx ny nz f_dc_0 f_dc_1 f_dc_2 opacity scale_0 scale_1 scale_2 \
                rot_0 rot_1 rot_2 rot_3 confidence";
    assert_eq!(props.join(" "), want);
    assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
    assert!(header.contains("\nelement vertex 1\n"));
    let body: Vec<f32> = bytes[body_at..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let want = [
        1.0,
        2.0,
        3.0,
        0.0,
        0.0,
        0.0,
        0.0,
        1.0,
        -0.5 / SH_C0 as f32,
        0.0,
        -1.0,
        -2.0,
        -3.0,
        0.9,
        0.1,
        0.2,
        0.3,
        0.25,
    ];
    assert_eq!(body.len(), want.len());
    for (k, (a, b)) in body.iter().zip(want).enumerate() {
        assert!((a - b).abs() < 1e-6, "property {k}: {a} vs {b}");
    }
}

#[test]
fn extreme_opacities_are_clamped_to_finite_logits() {
    let mut set = sample_set();
    set.opacities[0] = 0.0;
    set.opacities[1] = 1.0;
    set.opacities[2] = f32::NAN;
    let back = read_ply(to_bytes(&set).as_slice()).unwrap();
    assert!((back.opacities[0] - 1e-6).abs() < 1e-9);
    assert!((back.opacities[1] - (1.0 - 1e-6)).abs() < 1e-7);
    assert!(back.opacities[2].is_nan(), "NaN is data, passed through");
}

/// Little-endian byte builder for hand-written files.
#[derive(Default)]
struct Le(Vec<u8>);

impl Le {
    fn f32(&mut self, v: f32) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn f64(&mut self, v: f64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn bytes(&mut self, v: &[u8]) -> &mut Self {
        self.0.extend_from_slice(v);
        self
    }
}

/// A foreign-looking binary file: comments, an element with a list before `vertex`, a double
/// `x`, normals, 45 `f_rest_*`, scale and rotation in another order, `uchar` colours, no
/// confidence, a `face` element after. Returns the file and the byte length through vertex.
fn foreign_file(format: &str) -> (Vec<u8>, usize) {
    let mut h = format!("ply\r\nformat {format} 1.0\ncomment made by hand\nobj_info x\n");
    h += "comment caf\u{e9}\n"; // Latin-1 below: comments need not be UTF-8.
    h += "element camera 2\nproperty float fx\nproperty list uchar int ids\nproperty short k\n";
    h += "element vertex 2\nproperty double x\nproperty float y\nproperty float z\n";
    h += "property float nx\nproperty float ny\nproperty float nz\n";
    for k in ["f_dc_0", "f_dc_1", "f_dc_2"] {
        h += &format!("property float {k}\n");
    }
    for k in 0..45 {
        h += &format!("property float f_rest_{k}\n");
    }
    h += "property float32 opacity\n";
    for k in [
        "rot_0", "rot_1", "rot_2", "rot_3", "scale_0", "scale_1", "scale_2",
    ] {
        h += &format!("property float {k}\n");
    }
    h += "property uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let mut b = Le(h.replace('\u{e9}', "\u{1}").into_bytes());
    let latin1 = b.0.iter().position(|&c| c == 1).unwrap();
    b.0[latin1] = 0xe9;
    b.f32(500.0).bytes(&[2, 1, 0, 0, 0, 2, 0, 0, 0, 7, 0]); // camera 0: two ids
    b.f32(600.0).bytes(&[0, 0xff, 0xff]); // camera 1: no ids, k = -1
    for i in 0..2 {
        let s = i as f32;
        b.f64(1.0 + s as f64)
            .f32(2.0)
            .f32(3.0)
            .f32(0.0)
            .f32(0.0)
            .f32(1.0);
        b.f32(0.0).f32(1.0).f32(-1.0);
        for k in 0..45 {
            b.f32(k as f32);
        }
        b.f32(0.0).f32(1.0).f32(0.0).f32(0.0).f32(s); // opacity, rot (w x y z)
        b.f32(-1.0).f32(-2.0).f32(-3.0).bytes(&[200]);
    }
    let through_vertex = b.0.len();
    b.bytes(&[3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
    (b.0, through_vertex)
}

fn check_foreign(set: &GaussianSet) {
    assert_eq!(set.len(), 2);
    for i in 0..2 {
        let g = set.get(i);
        assert_eq!(g.mean, Vec3::new(1.0 + i as f32, 2.0, 3.0));
        assert_eq!(g.log_scale, Vec3::new(-1.0, -2.0, -3.0));
        assert_eq!(g.rotation, Quat::from_xyzw(0.0, 0.0, i as f32, 1.0));
        assert_eq!(g.opacity, 0.5);
        let c = SH_C0 as f32;
        assert!(
            (g.color - Vec3::new(0.5, 0.5 + c, 0.5 - c))
                .abs()
                .max_element()
                < 1e-7
        );
        assert_eq!(g.confidence, 1.0, "absent confidence defaults to 1");
    }
}

#[test]
fn a_foreign_binary_file_reads() {
    let (bytes, _) = foreign_file("binary_little_endian");
    check_foreign(&read_ply(bytes.as_slice()).unwrap());
}

/// The same records as [`foreign_file`] in an ascii file.
fn foreign_ascii() -> Vec<u8> {
    let (binary, _) = foreign_file("ascii");
    let mut text = String::from("500 2 1 2 7\n600 0 -1\n");
    for i in 0..2 {
        text += &format!("{} 2 3 0 0 1 0 1 -1 ", 1 + i);
        text += &(0..45).map(|k| format!("{k} ")).collect::<String>();
        text += &format!("0 1 0 0 {i} -1 -2 -3 200\n");
    }
    text += "3 0 1 2\n";
    [&binary[..body_start(&binary)], text.as_bytes()].concat()
}

/// Where the data starts: just after `end_header\n`.
fn body_start(bytes: &[u8]) -> usize {
    let end = b"end_header\n";
    bytes.windows(end.len()).position(|w| w == end).unwrap() + end.len()
}

#[test]
fn a_foreign_ascii_file_reads() {
    check_foreign(&read_ply(foreign_ascii().as_slice()).unwrap());
}

/// Our own file with its header rewritten by `edit`.
fn edited(edit: impl Fn(&str) -> String) -> Vec<u8> {
    let bytes = to_bytes(&sample_set());
    let at = body_start(&bytes) - b"end_header\n".len();
    let header = std::str::from_utf8(&bytes[..at]).unwrap();
    let mut out = edit(header).into_bytes();
    out.extend_from_slice(&bytes[at..]);
    out
}

fn read_err(bytes: &[u8]) -> PlyError {
    read_ply(bytes).expect_err("this input must be refused")
}

#[test]
fn not_ply_and_unsupported_formats() {
    assert!(matches!(read_err(b""), PlyError::NotPly));
    assert!(matches!(read_err(b"hello\nworld\n"), PlyError::NotPly));
    assert!(matches!(read_err(&[0xff; 100_000]), PlyError::NotPly));
    let big = edited(|h| h.replace("binary_little_endian", "binary_big_endian"));
    assert!(matches!(read_err(&big), PlyError::UnsupportedFormat(f) if f == "binary_big_endian"));
    let v2 = edited(|h| h.replace("endian 1.0", "endian 2.0"));
    assert!(matches!(read_err(&v2), PlyError::UnsupportedFormat(_)));
    let list = edited(|h| h.replace("property float nx", "property list uchar float nx"));
    assert!(matches!(read_err(&list), PlyError::UnsupportedFormat(_)));
}

#[test]
fn bad_headers_name_their_line() {
    let cases = [
        ("property float y", "property half y", 6),
        ("element vertex 303", "element vertex -3", 4),
        ("element vertex 303", "element vertex many", 4),
        ("format binary_little_endian 1.0\n", "", 22),
        ("comment", "property float a\ncomment", 3),
        ("property float z", "property float y", 7),
        ("comment", "bogus", 3),
    ];
    for (k, (from, to, want_line)) in cases.into_iter().enumerate() {
        match read_err(&edited(|h| h.replace(from, to))) {
            PlyError::BadHeader { line, .. } => assert_eq!(line, want_line, "case {k}"),
            other => panic!("case {k}: {other:?}"),
        }
    }
    let no_end = b"ply\nformat ascii 1.0\nelement vertex 1\n";
    assert!(matches!(
        read_err(no_end),
        PlyError::BadHeader { line: 4, .. }
    ));
    let long = format!("ply\n{}", "comment a long one\n".repeat(5000));
    assert!(matches!(
        read_err(long.as_bytes()),
        PlyError::BadHeader { .. }
    ));
    let bad_list = edited(|h| {
        h.replace(
            "element vertex",
            "element e 0\nproperty list float int i\nelement vertex",
        )
    });
    assert!(matches!(
        read_err(&bad_list),
        PlyError::BadHeader { line: 5, .. }
    ));
}

#[test]
fn missing_parts_are_named() {
    let no_vertex = edited(|h| h.replace("element vertex", "element point"));
    assert!(matches!(read_err(&no_vertex), PlyError::MissingElement(e) if e == "vertex"));
    let no_rot3 = edited(|h| h.replace("rot_3", "rot_x"));
    assert!(matches!(read_err(&no_rot3), PlyError::MissingProperty(p) if p == "rot_3"));
}

#[test]
fn truncation_reports_the_sizes() {
    let bytes = to_bytes(&sample_set());
    let data = (sample_set().len() * 18 * 4) as u64;
    let err = read_err(&bytes[..bytes.len() - 5]);
    assert!(
        matches!(err, PlyError::Truncated { expected_bytes, got_bytes } if expected_bytes == data && got_bytes == data - 5),
        "{err:?}"
    );
}

#[test]
fn hostile_counts_are_refused_before_allocating() {
    // More records than any file can hold: refused from the header alone.
    let huge = edited(|h| h.replace("element vertex 303", "element vertex 18446744073709551615"));
    let err = read_err(&huge);
    assert!(
        matches!(
            err,
            PlyError::TooLarge {
                available_bytes: None,
                ..
            }
        ),
        "{err:?}"
    );
    // A streamed reader cannot know the length: it reads what is there, then stops.
    let many = edited(|h| h.replace("element vertex 303", "element vertex 1000000000000"));
    assert!(matches!(read_err(&many), PlyError::Truncated { .. }));
    // A file's length is known: refused before reading any record.
    let path = std::env::temp_dir().join(format!("renderer-ply-huge-{}.ply", std::process::id()));
    std::fs::write(&path, &many).unwrap();
    let loaded = load_ply(&path);
    std::fs::remove_file(&path).unwrap();
    match loaded {
        Err(PlyError::TooLarge {
            element,
            count,
            available_bytes,
            ..
        }) => {
            assert_eq!((element.as_str(), count), ("vertex", 1_000_000_000_000));
            assert_eq!(available_bytes, Some(303 * 72));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn bad_data_and_io_errors() {
    let negative_list = edited(|h| {
        h.replace(
            "element vertex",
            "element e 1\nproperty list char int i\nelement vertex",
        )
    });
    let mut bytes = negative_list;
    let at = body_start(&bytes);
    bytes.insert(at, 0xff); // list length -1
    assert!(matches!(
        read_err(&bytes),
        PlyError::BadData { record: 0, .. }
    ));
    let ascii = b"ply\nformat ascii 1.0\nelement e 1\nproperty float a\nend_header\nnope\n";
    assert!(matches!(read_err(ascii), PlyError::MissingElement(_)));
    let ascii = String::from_utf8_lossy(ascii).replace("element e", "element vertex");
    let ascii = ascii.replace("property float a\n", &{
        let (b, _) = foreign_file("ascii");
        let s = String::from_utf8_lossy(&b).to_string();
        let start = s.find("property double x").unwrap();
        let end = s.find("element face").unwrap();
        s[start..end].to_owned()
    });
    assert!(matches!(
        read_err(ascii.as_bytes()),
        PlyError::BadData { record: 0, .. }
    ));
    assert!(matches!(
        load_ply("/nonexistent/dir/x.ply"),
        Err(PlyError::Io(_))
    ));
    let mut set = sample_set();
    set.colors.pop();
    assert!(matches!(
        write_ply(&set, Vec::new()),
        Err(PlyError::LengthMismatch(_))
    ));
}

#[test]
fn no_input_makes_the_reader_panic() {
    let (foreign, through_vertex) = foreign_file("binary_little_endian");
    let ours = to_bytes(&sample_set());
    // Every truncation: an error before the end of the vertex data, the set after it.
    for cut in 0..foreign.len() {
        let got = read_ply(&foreign[..cut]);
        assert_eq!(got.is_ok(), cut >= through_vertex, "cut at {cut}: {got:?}");
    }
    for cut in (0..ours.len()).step_by(7) {
        assert!(read_ply(&ours[..cut]).is_err());
    }
    // Random byte changes, in the header or in the data, sometimes cut short too.
    let ascii = foreign_ascii();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut oks = 0;
    for case in 0..4000 {
        let base = [&foreign, &ascii, &ours][case % 3];
        let mut bytes = base.clone();
        let data = body_start(base);
        let region = match case % 2 {
            0 => 0..data,
            _ => data..bytes.len(),
        };
        for _ in 0..rng.random_range(1..4) {
            let at = rng.random_range(region.clone());
            bytes[at] = match rng.random_range(0..4) {
                0 => rng.random(),
                1 => bytes[at] ^ (1 << rng.random_range(0..8)),
                2 => b"0123456789 \n-."[rng.random_range(0..14)],
                _ => b'9',
            };
        }
        let cut = match rng.random_range(0..4) {
            0 => rng.random_range(0..=bytes.len()),
            _ => bytes.len(),
        };
        oks += read_ply(&bytes[..cut]).is_ok() as usize;
    }
    assert!(oks > 100, "many data changes are harmless: {oks}");
}
