//! The SGM baseline against scenes with known geometry: stereo pairs rendered by the CPU
//! rasterizer from Gaussians (textured planes, the renderer's street), with the rendered
//! depth or the plane's depth as ground truth.

use glam::{Mat3, Quat, Vec3};
use model::baseline::{disparity, Paths, SgmConfig, SgmReconstructor};
use model::frame::RgbImage;
use model::reconstruct::{ReconstructError, Reconstructor, StereoView};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use renderer::{Camera, Gaussian, GaussianSet, Intrinsics, RenderSettings};

const BASELINE: f32 = 0.6;

/// KITTI-360-like intrinsics at 544x112.
fn intrinsics() -> Intrinsics {
    Intrinsics {
        fx: 213.0,
        fy: 213.0,
        cx: 271.5,
        cy: 55.5,
        width: 544,
        height: 112,
    }
}

fn left_camera() -> Camera {
    Camera::identity(intrinsics())
}

fn right_camera() -> Camera {
    Camera::from_camera_to_world(intrinsics(), Quat::IDENTITY, Vec3::X * BASELINE)
}

/// Renders `set` from `camera`: the image and the rendered depth (0 where empty).
pub(crate) fn render(set: &GaussianSet, camera: &Camera) -> (RgbImage, Vec<f32>) {
    let view = set.view().expect("consistent set");
    let out =
        renderer::cpu::render(&view, &camera.params::<f32>(), &RenderSettings::default()).output;
    let image = RgbImage {
        width: out.width,
        height: out.height,
        data: out.rgb,
    };
    (image, out.depth)
}

/// A fronto-parallel plane at depth `z` spanning `x` and `y` (metres), tiled with opaque
/// flat discs one pixel apart for a camera of focal `fx`, each a random grey-ish colour (a
/// noise texture).
pub(crate) fn plane(set: &mut GaussianSet, fx: f32, z: f32, x: [f32; 2], y: [f32; 2], seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let step = z / fx;
    let (nx, ny) = (
        ((x[1] - x[0]) / step) as usize,
        ((y[1] - y[0]) / step) as usize,
    );
    for j in 0..=ny {
        for i in 0..=nx {
            let base: f32 = rng.random_range(0.1..0.9);
            set.push(Gaussian {
                mean: Vec3::new(x[0] + i as f32 * step, y[0] + j as f32 * step, z),
                log_scale: Vec3::new(0.8 * step, 0.8 * step, 0.05 * step).ln(),
                rotation: Quat::IDENTITY,
                opacity: 1.0,
                color: Vec3::new(base, base * 0.9 + 0.05, base * 0.8 + 0.1),
                confidence: 1.0,
            });
        }
    }
}

/// A plane at depth `z` covering both cameras' views.
fn wall(set: &mut GaussianSet, z: f32, seed: u64) {
    let k = intrinsics();
    let half_w = (k.cx + 4.0) / k.fx * z;
    let half_h = (k.cy + 4.0) / k.fy * z;
    plane(
        set,
        k.fx,
        z,
        [-half_w, half_w + BASELINE],
        [-half_h, half_h],
        seed,
    );
}

fn view<'a>(left: &'a RgbImage, right: &'a RgbImage) -> StereoView<'a> {
    StereoView {
        left,
        right,
        left_camera: left_camera(),
        right_camera: right_camera(),
    }
}

fn median(mut v: Vec<f32>) -> f32 {
    assert!(!v.is_empty());
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

/// Whether every field of every Gaussian is finite and confidences lie in (0, 1].
pub(crate) fn all_finite(set: &GaussianSet) -> bool {
    set.check_lengths().is_ok()
        && set.means.iter().all(|m| m.is_finite())
        && set.log_scales.iter().all(|s| s.is_finite())
        && set.colors.iter().all(|c| c.is_finite())
        && set.opacities.iter().all(|o| o.is_finite())
        && set
            .confidences
            .iter()
            .all(|c| c.is_finite() && *c > 0.0 && *c <= 1.0)
}

#[test]
fn a_textured_plane_gives_its_disparity_within_a_quarter_pixel() {
    // Disparities 15.98 px (near an integer) and 17.5 px (half way, where sub-pixel matters).
    let fxb = intrinsics().fx * BASELINE;
    for (z, paths) in [
        (8.0, Paths::Eight),
        (8.0, Paths::Five),
        (fxb / 17.5, Paths::Eight),
    ] {
        let mut set = GaussianSet::default();
        wall(&mut set, z, 1);
        let (left, _) = render(&set, &left_camera());
        let (right, _) = render(&set, &right_camera());
        let config = SgmConfig {
            paths,
            ..SgmConfig::default()
        };
        let map = disparity(&left, &right, &config).unwrap();
        check_plane(&map, z);
    }
}

/// The disparity of the plane at depth `z` is valid and exact on the matchable columns.
fn check_plane(map: &model::baseline::DisparityMap, z: f32) {
    let truth = intrinsics().fx * BASELINE / z;
    let w = map.width as usize;
    // Columns left of the largest disparity cannot be matched at all; judge the rest.
    let judged: Vec<usize> = (0..map.disparity.len()).filter(|i| i % w >= 140).collect();
    let valid: Vec<f32> = judged
        .iter()
        .map(|&i| map.disparity[i])
        .filter(|d| !d.is_nan())
        .collect();
    let fraction = valid.len() as f32 / judged.len() as f32;
    let err = median(valid.iter().map(|d| (d - truth).abs()).collect());
    println!("plane: truth {truth:.3} px, valid {fraction:.3}, median |error| {err:.3} px");
    assert!(fraction > 0.9, "valid fraction {fraction}");
    assert!(err < 0.25, "median disparity error {err} px");
}

#[test]
fn the_street_is_recovered_and_its_render_matches_the_left_image() {
    let k = intrinsics();
    let scene = renderer::scene::pixel_aligned(3, &k, 2, BASELINE);
    let (left, depth) = render(&scene, &left_camera());
    let (right, _) = render(&scene, &right_camera());
    let mut sgm = SgmReconstructor::new(SgmConfig::default());
    let start = std::time::Instant::now();
    let map = sgm.view_disparity(&view(&left, &right)).unwrap();
    println!("disparity of a 544x112 pair: {:?}", start.elapsed());
    // Textured, measurable surfaces: road and facades nearer than 40 m.
    let judged: Vec<usize> = (0..depth.len())
        .filter(|&i| depth[i] > 0.0 && depth[i] < 40.0 && i % k.width as usize >= 80)
        .collect();
    let errors: Vec<f32> = judged
        .iter()
        .filter(|&&i| !map.disparity[i].is_nan())
        .map(|&i| {
            let z = k.fx * BASELINE / map.disparity[i];
            (z - depth[i]).abs() / depth[i]
        })
        .collect();
    let fraction = errors.len() as f32 / judged.len() as f32;
    let rel = median(errors);
    println!("street: valid {fraction:.3}, median |dz|/z {rel:.4}");
    assert!(fraction > 0.7, "valid fraction {fraction}");
    assert!(rel < 0.03, "median relative depth error {rel}");

    let set = sgm.reconstruct(&[view(&left, &right)]).unwrap();
    assert!(all_finite(&set));
    let (render_left, _) = render(&set, &left_camera());
    let (mut se, mut n) = (0.0f64, 0usize);
    for (i, d) in map.disparity.iter().enumerate() {
        if !d.is_nan() && depth[i] < 40.0 {
            for c in 0..3 {
                let e = (render_left.data[3 * i + c] - left.data[3 * i + c]) as f64;
                se += e * e;
            }
            n += 3;
        }
    }
    let psnr = 10.0 * (1.0 / (se / n as f64)).log10();
    println!(
        "street: {} Gaussians, PSNR on valid pixels {psnr:.2} dB",
        set.len()
    );
    assert!(psnr > 25.0, "PSNR {psnr}");
}

#[test]
fn pixels_occluded_in_the_right_view_are_rejected() {
    let (z_wall, z_box, half) = (12.0, 4.0, 0.4);
    let mut set = GaussianSet::default();
    wall(&mut set, z_wall, 2);
    plane(
        &mut set,
        intrinsics().fx,
        z_box,
        [-half, half],
        [-2.0, 2.0],
        3,
    );
    let (left, _) = render(&set, &left_camera());
    let (right, _) = render(&set, &right_camera());
    let map = disparity(&left, &right, &SgmConfig::default()).unwrap();
    let k = intrinsics();
    let (d_wall, d_box) = (k.fx * BASELINE / z_wall, k.fx * BASELINE / z_box);
    let box_left = k.cx - k.fx * half / z_box;
    // Wall pixels in [box_left - (d_box - d_wall), box_left] are hidden by the box in the
    // right image; keep two columns of margin on each side.
    let band = (box_left - (d_box - d_wall) + 2.0).ceil() as usize..(box_left - 2.0) as usize;
    let w = k.width as usize;
    let count = |cols: std::ops::Range<usize>, pred: &dyn Fn(f32) -> bool| {
        let idx: Vec<usize> = (0..map.disparity.len())
            .filter(|i| cols.contains(&(i % w)))
            .collect();
        idx.iter().filter(|&&i| pred(map.disparity[i])).count() as f32 / idx.len() as f32
    };
    let rejected = count(band.clone(), &|d| d.is_nan());
    let wall_ok = count(60..200, &|d| (d - d_wall).abs() < 1.0);
    let box_ok = count(256..288, &|d| (d - d_box).abs() < 1.0);
    println!(
        "occlusion band {band:?}: rejected {rejected:.3}; wall ok {wall_ok:.3}; box ok {box_ok:.3}"
    );
    assert!(rejected > 0.8, "occluded pixels rejected: {rejected}");
    assert!(
        wall_ok > 0.9 && box_ok > 0.9,
        "wall {wall_ok}, box {box_ok}"
    );
}

#[test]
fn uniform_images_give_few_gaussians_and_nothing_non_finite() {
    let k = intrinsics();
    for value in [0.0f32, 0.5] {
        let mut image = RgbImage::new(k.width, k.height);
        image.data.fill(value);
        let set = SgmReconstructor::default()
            .reconstruct(&[view(&image, &image)])
            .unwrap();
        println!("uniform {value}: {} Gaussians", set.len());
        assert!(
            set.len() < 100,
            "{} Gaussians on a uniform image",
            set.len()
        );
        assert!(all_finite(&set));
    }
}

#[test]
fn non_finite_pixels_give_finite_gaussians() {
    let mut set = GaussianSet::default();
    wall(&mut set, 8.0, 6);
    let (mut left, _) = render(&set, &left_camera());
    let (right, _) = render(&set, &right_camera());
    for (i, v) in left.data.iter_mut().enumerate().step_by(97) {
        *v = if i % 2 == 0 { f32::NAN } else { f32::INFINITY };
    }
    let out = SgmReconstructor::default()
        .reconstruct(&[view(&left, &right)])
        .unwrap();
    println!("non-finite pixels: {} Gaussians", out.len());
    assert!(out.len() > 30_000);
    assert!(all_finite(&out));
}

#[test]
fn identical_images_mean_zero_disparity_and_everything_is_pruned() {
    let mut set = GaussianSet::default();
    wall(&mut set, 8.0, 4);
    let (left, _) = render(&set, &left_camera());
    let map = disparity(&left, &left, &SgmConfig::default()).unwrap();
    let valid: Vec<f32> = map
        .disparity
        .iter()
        .copied()
        .filter(|d| !d.is_nan())
        .collect();
    let d = median(valid.clone());
    println!("identical: {} valid, median disparity {d}", valid.len());
    assert!(d.abs() < 0.1);
    assert!(map.confidence.iter().all(|c| c.is_finite()));
    let out = SgmReconstructor::default()
        .reconstruct(&[view(&left, &left)])
        .unwrap();
    assert!(out.len() < 50, "{} Gaussians", out.len());
    assert!(all_finite(&out));
}

#[test]
fn the_gaussian_count_follows_stride_and_cap_and_views_concatenate() {
    let mut set = GaussianSet::default();
    wall(&mut set, 8.0, 5);
    let (left, _) = render(&set, &left_camera());
    let (right, _) = render(&set, &right_camera());
    let pair = view(&left, &right);
    let full = SgmReconstructor::default().reconstruct(&[pair]).unwrap();
    let quarter = SgmReconstructor::new(SgmConfig {
        stride: 2,
        ..SgmConfig::default()
    })
    .reconstruct(&[pair])
    .unwrap();
    let ratio = quarter.len() as f32 / full.len() as f32;
    println!(
        "stride 1: {}, stride 2: {} ({ratio:.3})",
        full.len(),
        quarter.len()
    );
    assert!(full.len() > 40_000);
    let z = median(full.means.iter().map(|m| m.z).collect());
    assert!(
        (z - 8.0).abs() < 0.05,
        "median Gaussian depth {z} for a plane at 8 m"
    );
    assert!((0.22..0.28).contains(&ratio), "ratio {ratio}");
    let capped = SgmReconstructor::new(SgmConfig {
        max_gaussians: 1000,
        ..SgmConfig::default()
    })
    .reconstruct(&[pair])
    .unwrap();
    assert_eq!(capped.len(), 1000);

    // A second view one metre further along z: its Gaussians are the first view's, shifted.
    let ahead = |c: Camera| Camera {
        position: c.position + Vec3::Z,
        ..c
    };
    let moved = StereoView {
        left_camera: ahead(pair.left_camera),
        right_camera: ahead(pair.right_camera),
        ..pair
    };
    let both = SgmReconstructor::default()
        .reconstruct(&[pair, moved])
        .unwrap();
    assert_eq!(both.len(), 2 * full.len());
    let shift = both.means[full.len()..]
        .iter()
        .zip(&full.means)
        .map(|(b, a)| (*b - *a - Vec3::Z).length())
        .fold(0.0f32, f32::max);
    assert!(shift < 1e-4, "second view offset error {shift}");
}

#[test]
fn unrectified_or_mismatched_input_is_invalid() {
    let k = intrinsics();
    let image = RgbImage::new(k.width, k.height);
    let small = RgbImage::new(k.width / 2, k.height);
    let invalid = |v: StereoView<'_>| {
        matches!(
            SgmReconstructor::default().reconstruct(&[v]),
            Err(ReconstructError::InvalidInput(_))
        )
    };
    let pair = view(&image, &image);
    let rotated = Camera {
        rotation: Mat3::from_rotation_y(0.05),
        ..right_camera()
    };
    let raised = Camera {
        position: Vec3::new(BASELINE, 0.1, 0.0),
        ..right_camera()
    };
    let other_k = Camera {
        intrinsics: Intrinsics { fx: 200.0, ..k },
        ..right_camera()
    };
    let swapped = StereoView {
        left_camera: right_camera(),
        right_camera: left_camera(),
        ..pair
    };
    for (name, v) in [
        (
            "rotated",
            StereoView {
                right_camera: rotated,
                ..pair
            },
        ),
        (
            "raised",
            StereoView {
                right_camera: raised,
                ..pair
            },
        ),
        (
            "intrinsics",
            StereoView {
                right_camera: other_k,
                ..pair
            },
        ),
        ("swapped", swapped),
        (
            "size",
            StereoView {
                right: &small,
                ..pair
            },
        ),
    ] {
        assert!(invalid(v), "{name} accepted");
    }
    assert!(matches!(
        disparity(&image, &small, &SgmConfig::default()),
        Err(ReconstructError::InvalidInput(_))
    ));
    for config in [
        SgmConfig {
            p1: 100,
            p2: 50,
            ..SgmConfig::default()
        },
        SgmConfig {
            p2: 9000,
            ..SgmConfig::default()
        },
        SgmConfig {
            stride: 0,
            ..SgmConfig::default()
        },
        SgmConfig {
            footprint_scale: -1.0,
            ..SgmConfig::default()
        },
        SgmConfig {
            max_depth: 0.05,
            ..SgmConfig::default()
        },
        SgmConfig {
            min_search_fraction: 0.0,
            ..SgmConfig::default()
        },
    ] {
        assert!(
            matches!(
                SgmReconstructor::new(config.clone()).reconstruct(&[pair]),
                Err(ReconstructError::InvalidInput(_))
            ),
            "{config:?} accepted"
        );
    }
    assert!(matches!(
        SgmReconstructor::default().reconstruct(&[]),
        Err(ReconstructError::NoViews)
    ));
}
