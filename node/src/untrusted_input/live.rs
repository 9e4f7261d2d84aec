//! The entries of decoders that live in the running node's modules (the `runtime` feature):
//! the worker protocol, the input path, snapshot region queries, the live view's HTTP
//! parameters, snapshot attachment and topics, and ROS `camera_calibration` YAML files.
//! Their fuzz targets build `node` with that feature (docs/fuzzing.md).

use std::sync::OnceLock;

use glam::{DAffine3, DQuat, DVec3};
use model::frame::{RgbImage, StereoFrame, StereoRig};

use super::{frames, scratch_file, split, MAX_FRAMES};
use crate::fusion::{FusionConfig, GlobalMap};
use crate::msg::gaussians::cloud_from_gaussians;
use crate::msg::image::image_from_rgb;
use crate::msg::std_msgs::Header;
use crate::pair::calib::{read_camera_info, CalibrationInput};
use crate::pipeline::self_check::OnCheckFail;
use crate::pipeline::worker::{Job, Stamps};
use crate::remote::admit::{admit_map, admit_render, Rules};
use crate::remote::wire::{Reply, Request, REQUEST_PREFIX};
use crate::service::inputs::{feed, INPUT_TOPICS, POSE_SOURCE_TOPICS};
use crate::service::region::RegionQuery;
use crate::tf::{Mount, PoseSourceConfig, PoseSourceKind};
use crate::transport::keys::Topic;
use crate::view::{
    fetch_batch, paged_tiles, take_sample, tile_query, tiles_query, ViewState, DEFAULT_BUDGET,
    MAX_RADIUS_M,
};

/// A request to a worker process (`stereosplat worker`), as the worker reads it: its kind
/// from the first [`REQUEST_PREFIX`] bytes (a busy worker refuses a bin by them alone), then
/// the whole request decoded and what the worker reads of it before the reconstructor runs:
/// the fingerprint it compares, the frame and the rig.
pub fn worker_request(data: &[u8]) {
    if let Some(prefix) = data.get(..REQUEST_PREFIX) {
        let _ = Request::kind(prefix);
    }
    match Request::decode(data) {
        Ok(Request::Hello(fingerprint)) => {
            let _ = fingerprint.describe();
        }
        Ok(Request::Bin(job)) => {
            let _ = job.fingerprint.describe();
            let frame = &job.frame;
            let _ = (frame.left.data.len(), frame.right.data.len(), job.rig);
            let _ = crate::fusion::pose_problem(&frame.left_to_world);
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
}

/// A worker process's reply, as the node decodes it, then what the node does with it: a
/// map is admitted against a job of its own bin and pose ([`admit_map`]: the range checks
/// and the node's own self-check of the map), then fused into a global map and converted
/// to the bin map message; a render is admitted ([`admit_render`]) and converted to an
/// image message.
pub fn worker_reply(data: &[u8]) {
    match Reply::decode(data) {
        Ok(Reply::Hello(hello)) => {
            let _ = (hello.fingerprint.describe(), hello.threads);
        }
        Ok(Reply::Map(_, out)) => {
            let mut job = reply_job().clone();
            job.bin_id = out.bin_id;
            job.frame.left_to_world = out.bin_to_world;
            let rules = Rules {
                on_check_fail: OnCheckFail::Sgm,
                sgm_method: false,
                max_gaussians: usize::MAX,
            };
            let Ok(out) = admit_map(&job, &rules, *out) else {
                return;
            };
            let Ok(set) = &out.result else {
                return;
            };
            let header = Header::new(out.stamps.source_ns, "bin");
            let _ = cloud_from_gaussians(set, header, None);
            if let Ok(mut map) = GlobalMap::new(FusionConfig::default()) {
                let _ = map.insert_bin(out.bin_id, set, out.bin_to_world);
            }
        }
        Ok(Reply::Render(rendered)) => {
            let mut job = reply_job().clone();
            job.bin_id = rendered.bin_id;
            if let Ok(image) = &rendered.image {
                job.rig.intrinsics.width = image.width;
                job.rig.intrinsics.height = image.height;
            }
            let Ok(rendered) = admit_render(&job, rendered) else {
                return;
            };
            if let Ok(image) = &rendered.image {
                let _ = image_from_rgb(image, Header::new(rendered.render_end_ns, "bin"));
            }
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
}

/// The job replies are admitted against: a 32x16 pair of seeded noise from a rig of 0.5 m
/// (its bin and pose are replaced by the reply's, so the binding checks pass and the range
/// checks and the self-check see the reply's content).
fn reply_job() -> &'static Job {
    static JOB: OnceLock<Job> = OnceLock::new();
    JOB.get_or_init(|| {
        let intrinsics = renderer::Intrinsics::from_hfov(32, 16, 80.0);
        let noise = |seed: u32| {
            let bytes: Vec<u8> = (0..3 * 32 * 16u32)
                .map(|i| (i.wrapping_mul(2_654_435_761).wrapping_add(seed) >> 13) as u8)
                .collect();
            RgbImage::from_rgb8(32, 16, &bytes)
        };
        Job {
            bin_id: 0,
            frame: StereoFrame {
                index: 0,
                left: noise(1),
                right: noise(2),
                left_to_world: DAffine3::IDENTITY,
            },
            rig: StereoRig {
                intrinsics,
                baseline: 0.5,
            },
            stamps: Stamps::default(),
            point: 0,
        }
    })
}

/// The node's whole input path (`Inputs::on_sample_at`, default limits and settings, fresh
/// counters): the input as one sample on each input topic, then as a stream of samples
/// ([`frames`]: each part's first byte picks the topic, left image, right image, left and
/// right camera info, pose, left and right compressed image, modulo 7; the rest is the
/// payload). Then both again with each pose source (`/tf` into `map`, and odometry with
/// its mount on `/tf_static`), `/tf`, `/tf_static` and odometry numbered 7, 8 and 9
/// (modulo 10).
pub fn node_inputs(data: &[u8]) {
    let tf = PoseSourceConfig::new(PoseSourceKind::Tf, Some("map".into()));
    let odometry = PoseSourceConfig::new(
        PoseSourceKind::Odometry {
            mount: Mount::TfStatic,
        },
        None,
    );
    let runs: [(&[Topic], Option<PoseSourceConfig>); 3] = [
        (&INPUT_TOPICS, None),
        (&POSE_SOURCE_TOPICS, Some(tf)),
        (&POSE_SOURCE_TOPICS, Some(odometry)),
    ];
    for (topics, source) in runs {
        let _ = feed(topics.iter().map(|&t| (t, data)), source.clone());
        let samples = frames(data, MAX_FRAMES).into_iter().filter_map(|part| {
            let (&topic, payload) = part.split_first()?;
            Some((topics[topic as usize % topics.len()], payload))
        });
        let _ = feed(samples, source);
    }
}

/// A snapshot query's parameters (the part of a zenoh selector after `?`, `k=v;k=v`, read as
/// UTF-8 with replacement), parsed by `RegionQuery::parse` as the node's queryable does, then
/// the region looked up in a small map and its reply's attachment made.
pub fn region_query(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let parameters = zenoh::query::Parameters::from(text.as_ref());
    let Ok(Some(region)) = RegionQuery::parse(parameters.iter()) else {
        return;
    };
    let map = small_map();
    let found = map.gaussians_in(region.min, region.max).len();
    let _ = map.paged_tiles_in(region.min, region.max);
    let pages = found.div_ceil(region.page_size).max(1);
    let _ = region.attachment(pages - 1, pages, found);
}

/// A map of one bin near the world origin, made once.
fn small_map() -> &'static GlobalMap {
    static MAP: OnceLock<GlobalMap> = OnceLock::new();
    MAP.get_or_init(|| {
        let k = renderer::Intrinsics::from_hfov(16, 8, 80.0);
        let set = renderer::scene::random_in_view(3, 24, &k);
        let pose = DAffine3::from_rotation_translation(
            DQuat::from_rotation_z(0.4),
            DVec3::new(3.0, -2.0, 1.5),
        );
        let mut map = GlobalMap::new(FusionConfig::default()).expect("the default settings");
        map.insert_bin(0, &set, pose).expect("a finite pose");
        map
    })
}

/// The query string of a live view request (`x=..&y=..`, UTF-8), as the view's server reads
/// it for `/api/tiles` and for `/map/tile.ply` (the URL parsed as hyper does, then the
/// parameters checked), each answered from a view holding a small map.
pub fn view_http_params(data: &[u8]) {
    let Ok(query) = std::str::from_utf8(data) else {
        return;
    };
    let parse = |path: &str| format!("{path}?{query}").parse::<axum::http::Uri>().ok();
    let gaussians: Vec<_> = small_map().gaussians().map(|(_, g)| *g).collect();
    let Some(mut state) = ViewState::saved(gaussians, 8.0) else {
        return;
    };
    if let Some(q) = parse("/api/tiles").and_then(|uri| tiles_query(&uri).ok()) {
        let _ = state.tiles_near(q.point, q.radius, q.budget).to_string();
    }
    if let Some(q) = parse("/map/tile.ply").and_then(|uri| tile_query(&uri).ok()) {
        let _ = state.tile_ply(q.tile, q.take);
    }
}

/// The JSON a whole-map snapshot reply attaches (the tile side and the tiles the node keeps
/// on disk), as the live view reads it into a fresh view; then the page's listing of the
/// tiles, its asking for them, and the region query the view makes to fetch them, parsed as
/// the node parses it.
pub fn view_snapshot_attachment(data: &[u8]) {
    let Some((side, tiles)) = paged_tiles(data) else {
        return;
    };
    let mut state = ViewState::default();
    state.adopt_tile_side(side);
    state.paged_on_node(side, &tiles);
    let _ = state
        .tiles_near(DVec3::ZERO, MAX_RADIUS_M, DEFAULT_BUDGET)
        .to_string();
    for &(tile, _) in tiles.iter().take(8) {
        let _ = state.tile_ply(tile, None);
    }
    if let Some((_, parameters)) = fetch_batch(&state.wanted_tiles()) {
        let parameters = zenoh::query::Parameters::from(parameters.as_str());
        let _ = RegionQuery::parse(parameters.iter());
    }
    let _ = state.to_json().to_string();
}

/// Messages on the node's topics as the live view takes them into its state (map updates
/// into its tiled copy, bin poses, renders and input images to PNG, latency, diagnostics,
/// camera info): the input as one message on each topic it watches, then as a stream of
/// messages ([`frames`]: each part's first byte picks the topic, in the order of
/// `view::take_sample`; the rest is the payload); then the page's JSON.
pub fn view_topics(data: &[u8]) {
    let mut state = ViewState::default();
    for n in 0..8 {
        let _ = take_sample(&mut state, n, data);
    }
    let mut state = ViewState::default();
    for part in frames(data, MAX_FRAMES) {
        if let Some((&n, payload)) = part.split_first() {
            let _ = take_sample(&mut state, n.into(), payload);
        }
    }
    let _ = state.to_json().to_string();
    let _ = state.map_ply();
    let _ = state.tiles_near(DVec3::ZERO, MAX_RADIUS_M, DEFAULT_BUDGET);
}

/// The left and right cameras' ROS `camera_calibration` YAML files (joined by a NUL, see
/// [`split`]) as `stereosplat reconstruct --camera-info L --camera-info-right R` reads them
/// for images of the size the left file names, and the left file alone with `--baseline`;
/// then the remap tables that rectify raw cameras' images.
pub fn camera_calibration(data: &[u8]) {
    let [left, right] = split::<2>(data);
    let left = scratch_file("left.yaml", left);
    let right = scratch_file("right.yaml", right);
    let size = read_camera_info(&left).map_or((640, 480), |info| (info.width, info.height));
    let both = CalibrationInput {
        camera_info: Some(left.clone()),
        camera_info_right: Some(right),
        ..CalibrationInput::default()
    };
    let alone = CalibrationInput {
        camera_info: Some(left),
        baseline: Some(0.12),
        ..CalibrationInput::default()
    };
    for input in [both, alone] {
        if let Ok(calibration) = input.resolve(size) {
            let _ = calibration.disparity_per_inverse_depth();
        }
        // The remap tables of raw cameras, for sizes whose tables build quickly (the
        // tables' cost is the image's size, bounded by the camera model's own limits).
        if u64::from(size.0) * u64::from(size.1) <= RECTIFIED_PIXELS {
            let _ = input.rectifier();
        }
    }
}

/// Largest image, in pixels, whose raw cameras [`camera_calibration`] rectifies.
const RECTIFIED_PIXELS: u64 = 1 << 16;
