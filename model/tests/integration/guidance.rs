//! SGM's hints (`sgm_guidance`) with the shipped `tiny` weights on a near textured plane:
//! they pull the first pair towards the plane and leave a later pair exactly as the network
//! alone predicts it (the hints were matched on the first pair only); with `sgm_snap` the
//! first pair's Gaussians SGM matched sit at SGM's depth, and with `sgm_fill` so do those of a
//! textureless band SGM cannot match. `tiny-3d` on the same plane runs without its
//! street-sized volume branch (`volume_branch_far_only`).

use candle_core::{Device, Tensor};
use model::net::{default_weights, Config, LearnedReconstructor, Prediction};
use renderer::{Camera, Intrinsics};

const WIDTH: usize = 128;
const HEIGHT: usize = 64;
/// fx 100 px, baseline 0.1 m, disparity 8 px: the plane lies 1.25 m away.
const PLANE_M: f32 = 1.25;

/// A textured left image and its right image for the plane (disparity 8 px), `(2, 3, H, W)`.
fn plane_pair() -> Tensor {
    let left: Vec<f32> = (0..HEIGHT * WIDTH)
        .map(|p| (((p * 2654435761usize) >> 9) % 251) as f32 / 251.0)
        .collect();
    // A point at left column x shows at right column x - disparity.
    let right: Vec<f32> = (0..HEIGHT * WIDTH)
        .map(|p| left[p - p % WIDTH + (p % WIDTH + 8).min(WIDTH - 1)])
        .collect();
    let planes = |v: &[f32]| Tensor::from_vec(v.repeat(3), (1, 3, HEIGHT, WIDTH), &Device::Cpu);
    Tensor::cat(&[planes(&left).unwrap(), planes(&right).unwrap()], 0).unwrap()
}

fn rig() -> [Camera; 2] {
    rig_at(glam::Vec3::ZERO)
}

/// The rig with its left camera at `origin`.
fn rig_at(origin: glam::Vec3) -> [Camera; 2] {
    let k = Intrinsics {
        fx: 100.0,
        fy: 100.0,
        cx: WIDTH as f32 / 2.0,
        cy: HEIGHT as f32 / 2.0,
        width: WIDTH as u32,
        height: HEIGHT as u32,
    };
    [0.0, 0.1]
        .map(|x| Camera::from_camera_to_world(k, glam::Quat::IDENTITY, origin + glam::Vec3::X * x))
}

/// Each view's depth map, flattened.
fn depths(prediction: &Prediction) -> Vec<Vec<f32>> {
    let v = prediction.depth.dim(0).unwrap();
    (0..v)
        .map(|i| {
            prediction
                .depth
                .get(i)
                .unwrap()
                .flatten_all()
                .unwrap()
                .to_vec1()
                .unwrap()
        })
        .collect()
}

/// The middle half of the Gaussians' grid columns (the borders see no match).
fn middle() -> std::ops::Range<usize> {
    WIDTH / 8..3 * WIDTH / 8
}

/// The cells of `depth` (a view's Gaussians, stride 2) in the grid columns `columns`.
fn cells_in(depth: &[f32], columns: std::ops::Range<usize>) -> Vec<f32> {
    let w = WIDTH / 2;
    (0..HEIGHT / 2)
        .flat_map(|y| columns.clone().map(move |x| depth[y * w + x]))
        .collect()
}

/// Mean |depth - plane| over the middle half of the columns.
fn plane_error(depth: &[f32]) -> f32 {
    let cells = cells_in(depth, middle());
    cells.iter().map(|d| (d - PLANE_M).abs()).sum::<f32>() / cells.len() as f32
}

#[test]
fn hints_guide_the_first_pair_towards_the_plane_and_no_later_pair() {
    // The hints alone, without the snap that replaces the depth where SGM matched.
    let cfg = Config::tiny().with_settings(&["sgm_snap=false"]).unwrap();
    assert!(cfg.sgm_guidance.is_some() && cfg.gaussian_stride == 2);
    let shipped = LearnedReconstructor::load(&cfg, &default_weights("tiny")).unwrap();
    // Two pairs: the second the first again, so guided or not it would give the same maps.
    let pair = plane_pair();
    let images = Tensor::cat(&[&pair, &pair], 0).unwrap();
    let cameras = [rig(), rig()].concat();
    let (fitted, range) = shipped
        .net()
        .fitted_to_scene(&images, &cameras)
        .expect("a textured plane is matched");
    let range = range.expect("a plane at 1.25 m is a near scene");
    assert!(range.near < PLANE_M && range.far > PLANE_M, "{range:?}");
    let predict = |net| {
        LearnedReconstructor::from_net(net, 0)
            .cost_volume_prediction(&images, &cameras)
            .unwrap()
    };
    let guided = depths(&predict(fitted.clone()));
    let alone = depths(&predict(fitted.without_hints()));
    for view in guided.iter().chain(&alone) {
        assert!(view.iter().all(|d| d.is_finite() && *d > 0.0));
    }
    // The later pair is exactly the network alone.
    assert_eq!(guided[2], alone[2]);
    assert_eq!(guided[3], alone[3]);
    // The first pair moves towards the plane.
    let (with, without) = (plane_error(&guided[0]), plane_error(&alone[0]));
    eprintln!("mean |depth - plane|: {with:.4} m with hints, {without:.4} m without");
    assert!(with < without, "{with} against {without}");
}

/// Share of `depth`'s middle-half cells within 3% of the plane (a quarter pixel of disparity).
fn on_plane(depth: &[f32]) -> f32 {
    on_plane_in(depth, middle())
}

/// Share of the cells of `depth` in the grid columns `columns` within 3% of the plane.
fn on_plane_in(depth: &[f32], columns: std::ops::Range<usize>) -> f32 {
    let cells = cells_in(depth, columns);
    cells
        .iter()
        .filter(|d| (*d - PLANE_M).abs() < 0.03 * PLANE_M)
        .count() as f32
        / cells.len() as f32
}

#[test]
fn snapped_gaussians_take_sgms_depth_on_the_first_pair_only_and_stay_finite_far_out() {
    let cfg = Config::tiny();
    assert!(cfg.sgm_snap);
    let shipped = LearnedReconstructor::load(&cfg, &default_weights("tiny")).unwrap();
    let pair = plane_pair();
    let images = Tensor::cat(&[&pair, &pair], 0).unwrap();
    // The rig at the origin and 100 km out: the snap works in the camera's frame.
    for offset in [glam::Vec3::ZERO, glam::Vec3::new(1.0e5, -1.0e5, 50.0)] {
        let cameras = [rig_at(offset), rig_at(offset)].concat();
        let (fitted, _) = shipped
            .net()
            .fitted_to_scene(&images, &cameras)
            .expect("a textured plane is matched");
        let predict = |net| {
            LearnedReconstructor::from_net(net, 0)
                .cost_volume_prediction(&images, &cameras)
                .unwrap()
        };
        let snapped = predict(fitted.clone());
        let alone = depths(&predict(fitted.without_hints()));
        let snapped_depths = depths(&snapped);
        let means: Vec<f32> = snapped
            .splats
            .means
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap();
        assert!(means.iter().all(|m| m.is_finite()), "{offset}");
        // SGM matches the 8-px plane exactly: nearly every middle Gaussian of both views of
        // the first pair sits on it, far more than the network alone puts there.
        for view in 0..2 {
            let (with, without) = (on_plane(&snapped_depths[view]), on_plane(&alone[view]));
            eprintln!("{offset} view {view}: {with:.3} of the cells on the plane snapped, {without:.3} alone");
            assert!(with > 0.9 && with > without, "{with} against {without}");
        }
        // The later pair is the network alone.
        assert_eq!(snapped_depths[2], alone[2]);
        assert_eq!(snapped_depths[3], alone[3]);
    }
}

/// The plane pair with the plane's left-image columns `BAND` one flat grey and the right
/// image's columns that show them an unrelated texture: nothing there for SGM to match,
/// and nothing that tells the network the plane goes on.
fn banded_plane_pair() -> Tensor {
    let pair = plane_pair();
    let noise: Vec<f32> = (0..3 * HEIGHT * BAND.len())
        .map(|p| (((p * 40503 + 7) >> 3) % 97) as f32 / 97.0)
        .collect();
    let flat = Tensor::cat(
        &[
            Tensor::full(0.5f32, (1, 3, HEIGHT, BAND.len()), &Device::Cpu).unwrap(),
            Tensor::from_vec(noise, (1, 3, HEIGHT, BAND.len()), &Device::Cpu).unwrap(),
        ],
        0,
    )
    .unwrap();
    // View `i` with its band's columns (the left image's shifted by `shift`: the right
    // image shows left column x at x - 8) replaced by `flat`'s view `i`.
    let banded = |i: usize, shift: usize| {
        let view = pair.get(i).unwrap().unsqueeze(0).unwrap();
        let (a, b) = (BAND.start - shift, BAND.end - shift);
        Tensor::cat(
            &[
                &view.narrow(3, 0, a).unwrap(),
                &flat.get(i).unwrap().unsqueeze(0).unwrap(),
                &view.narrow(3, b, WIDTH - b).unwrap(),
            ],
            3,
        )
        .unwrap()
    };
    Tensor::cat(&[banded(0, 0), banded(1, 8)], 0).unwrap()
}

/// Image columns of the banded pair's flat band.
const BAND: std::ops::Range<usize> = 48..80;

#[test]
fn filled_hints_put_a_textureless_band_on_the_plane_around_it() {
    let images = banded_plane_pair();
    let cameras = rig();
    let band = |settings: &[&str]| {
        let cfg = Config::tiny().with_settings(settings).unwrap();
        let shipped = LearnedReconstructor::load(&cfg, &default_weights("tiny")).unwrap();
        let (fitted, _) = shipped
            .net()
            .fitted_to_scene(&images, &cameras)
            .expect("the textured rest of the plane is matched");
        let prediction = LearnedReconstructor::from_net(fitted, 0)
            .cost_volume_prediction(&images, &cameras)
            .unwrap();
        let first = &depths(&prediction)[0];
        assert!(
            first.iter().all(|d| d.is_finite() && *d > 0.0),
            "{settings:?}"
        );
        on_plane_in(first, BAND.start / 2..BAND.end / 2)
    };
    assert!(Config::tiny().sgm_fill);
    let (filled, unfilled) = (band(&[]), band(&["sgm_fill=false"]));
    eprintln!("band cells on the plane: {filled:.3} filled, {unfilled:.3} without the fill");
    assert!(
        filled > 0.9 && filled > unfilled,
        "{filled} against {unfilled}"
    );
}

#[test]
fn tiny_3d_leaves_its_volume_branch_out_of_a_near_scene_only_when_told() {
    let pair = plane_pair();
    let cameras = rig();
    let volume_gaussians = |settings: &[&str]| {
        let cfg = Config::tiny_3d().with_settings(settings).unwrap();
        let mut net = LearnedReconstructor::load(&cfg, &default_weights("tiny-3d")).unwrap();
        let out = net.reconstruct_tensors(&pair, &cameras).unwrap();
        let report = net.last_report().unwrap();
        let range = report
            .depth_range
            .expect("a plane at 1.25 m is a near scene");
        assert!(range.near < PLANE_M && range.far > PLANE_M, "{range:?}");
        assert!(out.set.means.iter().all(|m| m.is_finite()), "{settings:?}");
        eprintln!("{settings:?}: {report:?}");
        assert!(report.cost_volume_gaussians > 100, "{report:?}");
        report.volume_gaussians
    };
    assert!(Config::tiny_3d().volume_branch_far_only);
    assert_eq!(volume_gaussians(&[]), 0);
    assert!(volume_gaussians(&["volume_branch_far_only=false"]) > 0);
}
