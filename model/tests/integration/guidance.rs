//! SGM's hints (`sgm_guidance`) with the shipped `tiny` weights on a near textured plane:
//! they pull the first pair towards the plane and leave a later pair exactly as the network
//! alone predicts it (the hints were matched on the first pair only).

use candle_core::{Device, Tensor};
use model::net::{default_weights, Config, LearnedReconstructor, Prediction};
use renderer::{Camera, Intrinsics};

const WIDTH: usize = 128;
const HEIGHT: usize = 64;
/// fx 100 px, baseline 0.1 m, disparity 8 px: the plane lies 1.25 m away.
const PLANE_M: f32 = 1.25;

/// A textured left image and its right image for the plane, `(2, 3, H, W)`.
fn plane_pair() -> Tensor {
    let left: Vec<f32> = (0..HEIGHT * WIDTH)
        .map(|p| (((p * 2654435761usize) >> 9) % 251) as f32 / 251.0)
        .collect();
    let right: Vec<f32> = (0..HEIGHT * WIDTH)
        .map(|p| left[p - p % WIDTH + (p % WIDTH + 8).min(WIDTH - 1)])
        .collect();
    let planes = |v: &[f32]| Tensor::from_vec(v.repeat(3), (1, 3, HEIGHT, WIDTH), &Device::Cpu);
    Tensor::cat(&[planes(&left).unwrap(), planes(&right).unwrap()], 0).unwrap()
}

fn rig() -> [Camera; 2] {
    let k = Intrinsics {
        fx: 100.0,
        fy: 100.0,
        cx: WIDTH as f32 / 2.0,
        cy: HEIGHT as f32 / 2.0,
        width: WIDTH as u32,
        height: HEIGHT as u32,
    };
    [0.0, 0.1].map(|x| Camera::from_camera_to_world(k, glam::Quat::IDENTITY, glam::Vec3::X * x))
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

/// Mean |depth - plane| over the middle half of the columns (the borders see no match).
fn plane_error(depth: &[f32]) -> f32 {
    let (w, h) = (WIDTH / 2, HEIGHT / 2);
    let cells: Vec<f32> = (0..h)
        .flat_map(|y| (w / 4..3 * w / 4).map(move |x| depth[y * w + x]))
        .collect();
    cells.iter().map(|d| (d - PLANE_M).abs()).sum::<f32>() / cells.len() as f32
}

#[test]
fn hints_guide_the_first_pair_towards_the_plane_and_no_later_pair() {
    let cfg = Config::tiny();
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
