//! The seeds of the entries that need the `runtime` feature (`node::untrusted_input::live`):
//! worker requests and replies, input sample streams, region queries, the live view's
//! parameters, snapshot attachment and topics, and camera-info YAML files.

use glam::{DAffine3, DQuat, DVec3};
use model::consistency::{CheckReport, Verdict};
use model::frame::{RgbImage, StereoFrame, StereoRig};
use node::fusion::{increment_message, snapshot_message, FusionConfig, GlobalMap};
use node::msg::image::{camera_info, image_from_rgb};
use node::msg::pose::pose_from_affine;
use node::msg::sensor_msgs::CameraInfo;
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::pipeline::self_check::{CheckAction, CheckOutcome, OnCheckFail};
use node::pipeline::worker::{Output, Rendered, Stamps};
use node::remote::wire::{BinJob, Hello, Reply, Request};
use node::remote::Fingerprint;
use node::untrusted_input::join_frames;
use renderer::{GaussianSet, Intrinsics};

use super::{rgb, Seeds, STAMP};

/// Writes the seeds of every entry of `node::untrusted_input::live`. `k` is the seeds'
/// camera, `gaussians` a bin's map in its frame and `pose` a bin's pose.
pub fn write(
    seeds: &Seeds,
    k: &Intrinsics,
    gaussians: &GaussianSet,
    pose: DAffine3,
) -> anyhow::Result<()> {
    worker(seeds, k, gaussians, pose)?;
    inputs(seeds, k)?;
    view_topics(seeds, k, gaussians, pose)?;
    for (name, query) in [
        ("box", "box=-10,0.5,20,30"),
        ("around", "around=100,-50;radius=25;page_size=1000"),
    ] {
        seeds.put("region_query", name, query.as_bytes())?;
    }
    let view_fetch = node::view::fetch_batch(&[(
        (2, -1),
        (glam::DVec2::new(128.0, -64.0), glam::DVec2::new(192.0, 0.0)),
    )]);
    if let Some((_, parameters)) = view_fetch {
        seeds.put("region_query", "view_fetch", parameters.as_bytes())?;
    }
    for (name, query) in [
        ("tiles", "x=1.5&y=-2&radius=160&budget=1000000"),
        ("tile", "x=0&y=-1&v=3&take=2"),
    ] {
        seeds.put("view_http_params", name, query.as_bytes())?;
    }
    // What the node's snapshot queryable attaches to a whole-map reply.
    let attachment = serde_json::json!({
        "tile_m": 64.0,
        "paged_tiles": [[0, 0, 12], [1, -3, 4], [-2, 5, 1]],
        "truncated": false,
    });
    seeds.put(
        "view_snapshot_attachment",
        "three_tiles",
        attachment.to_string().as_bytes(),
    )?;
    let left = camera_yaml(&camera_info(k, 0.0, Header::new(STAMP, "left")));
    let right = camera_yaml(&camera_info(k, 0.6, Header::new(STAMP, "right")));
    seeds.put(
        "camera_calibration",
        "pair",
        format!("{left}\0{right}").as_bytes(),
    )?;
    seeds.put("camera_calibration", "left_only", left.as_bytes())?;
    Ok(())
}

/// Requests and replies of the worker protocol.
fn worker(
    seeds: &Seeds,
    k: &Intrinsics,
    gaussians: &GaussianSet,
    pose: DAffine3,
) -> anyhow::Result<()> {
    let fingerprint = Fingerprint {
        method: "stereosplat".into(),
        preset: "tiny".into(),
        settings: vec!["gaussian_stride=2".into()],
        weights_sha256: "ab".repeat(32),
    };
    let mut floats = RgbImage::new(k.width, k.height);
    floats.data[4] = 0.123_456_79;
    let job = BinJob {
        bin_id: 3,
        attempt: 1,
        fingerprint: fingerprint.clone(),
        on_check_fail: OnCheckFail::LowerOpacity,
        render: true,
        frame: StereoFrame {
            index: 17,
            left: rgb(k.width, k.height),
            right: floats,
            left_to_world: pose,
        },
        rig: StereoRig {
            intrinsics: *k,
            baseline: 0.6,
        },
        stamps: Stamps {
            source_ns: STAMP,
            arrival_ns: STAMP + 1_000,
            opened_ns: STAMP + 2_000,
            ..Stamps::default()
        },
    };
    seeds.put(
        "worker_request",
        "hello",
        &Request::Hello(fingerprint.clone()).encode(),
    )?;
    seeds.put(
        "worker_request",
        "bin",
        &Request::Bin(Box::new(job)).encode(),
    )?;
    let hello = Reply::Hello(Hello {
        fingerprint,
        threads: 2,
    });
    seeds.put("worker_reply", "hello", &hello.encode())?;
    let report = CheckReport {
        score: 0.25,
        coverage: 1.0,
        samples: 9,
        textured: 12,
        verdict: Verdict::Fail,
    };
    let output = |result| Output {
        bin_id: 3,
        bin_to_world: pose,
        result,
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
            model_end_ns: STAMP + 9_000,
            stage_end_ns: [1, 2, 3, 4, 5],
            ..Stamps::default()
        },
        queue_depth: 0,
        point: 0,
    };
    let map = Reply::Map(1, Box::new(output(Ok(gaussians.clone()))));
    seeds.put("worker_reply", "map", &map.encode())?;
    let failed = Reply::Map(0, Box::new(output(Err("reconstructor panicked".into()))));
    seeds.put("worker_reply", "map_error", &failed.encode())?;
    let render = Reply::Render(Rendered {
        bin_id: 3,
        image: Ok(rgb(k.width, k.height)),
        render_end_ns: STAMP + 10_000,
    });
    seeds.put("worker_reply", "render", &render.encode())?;
    Ok(())
}

/// Input samples: one message of each kind (the input as one sample on every topic), and
/// streams of samples (topic byte, then the payload) that open bins, at the seeds' camera
/// size and at one wider than the working size (downscaled when a bin opens).
fn inputs(seeds: &Seeds, k: &Intrinsics) -> anyhow::Result<()> {
    // Topic numbers of `node::untrusted_input::live::node_inputs`.
    const LEFT: u8 = 0;
    const RIGHT: u8 = 1;
    const LEFT_INFO: u8 = 2;
    const RIGHT_INFO: u8 = 3;
    const POSE: u8 = 4;
    let stream = |k: &Intrinsics, frames: i64| -> Vec<u8> {
        let sample = |topic: u8, payload: Vec<u8>| [vec![topic], payload].concat();
        let mut samples = vec![
            sample(
                LEFT_INFO,
                camera_info(k, 0.0, Header::new(STAMP, "left")).encode(),
            ),
            sample(
                RIGHT_INFO,
                camera_info(k, 0.6, Header::new(STAMP, "right")).encode(),
            ),
        ];
        for i in 0..frames {
            let stamp = STAMP + i * 100_000_000;
            let image =
                |frame: &str| image_from_rgb(&rgb(k.width, k.height), Header::new(stamp, frame));
            let pose = DAffine3::from_rotation_translation(
                DQuat::from_rotation_z(0.01 * i as f64),
                DVec3::new(5.0 * i as f64, 1.0, 0.5),
            );
            samples.push(sample(LEFT, image("left").encode()));
            samples.push(sample(RIGHT, image("right").encode()));
            samples.push(sample(
                POSE,
                pose_from_affine(&pose, Header::new(stamp, "world")).encode(),
            ));
        }
        let parts: Vec<&[u8]> = samples.iter().map(Vec::as_slice).collect();
        join_frames(&parts)
    };
    seeds.put("node_inputs", "drive", &stream(k, 3))?;
    let wide = Intrinsics::from_hfov(1416, 2, 80.0);
    seeds.put("node_inputs", "downscaled", &stream(&wide, 1))?;
    let image = image_from_rgb(&rgb(k.width, k.height), Header::new(STAMP, "left"));
    seeds.put("node_inputs", "image", &image.encode())?;
    let info = camera_info(k, 0.6, Header::new(STAMP, "right"));
    seeds.put("node_inputs", "camera_info", &info.encode())?;
    let pose = pose_from_affine(&DAffine3::IDENTITY, Header::new(STAMP, "world"));
    seeds.put("node_inputs", "pose", &pose.encode())?;
    Ok(())
}

/// The node's topics as the live view hears them: a stream (topic byte in the view's order,
/// then the payload) of a whole-map snapshot, the next increment, a bin pose, its render,
/// the bird's-eye view, its latency, the counters, a left image and its camera info; and
/// the snapshot alone (the input as one message on every topic).
fn view_topics(
    seeds: &Seeds,
    k: &Intrinsics,
    gaussians: &GaussianSet,
    pose: DAffine3,
) -> anyhow::Result<()> {
    // Topic numbers of `node::view::take_sample`.
    const MAP_UPDATE: u8 = 0;
    const BIN_POSE: u8 = 1;
    const BIN_RENDER: u8 = 2;
    const MAP_BEV: u8 = 3;
    const LATENCY: u8 = 4;
    const DIAGNOSTICS: u8 = 5;
    const LEFT_IMAGE: u8 = 6;
    const LEFT_INFO: u8 = 7;
    let world = || Header::new(STAMP, "world");
    let mut map = GlobalMap::new(FusionConfig::default())?;
    map.insert_bin(1, gaussians, pose)?;
    let snapshot = snapshot_message(&map.snapshot(), 1, world())?.encode();
    let next = DAffine3::from_translation(DVec3::new(6.0, 0.0, 0.0)) * pose;
    let increment = increment_message(&map.insert_bin(2, gaussians, next)?, 2, world())?;
    let picture = image_from_rgb(&rgb(k.width, k.height), Header::new(STAMP, "bin_2"));
    let samples = [
        (MAP_UPDATE, snapshot.clone()),
        (MAP_UPDATE, increment.encode()),
        (BIN_POSE, pose_from_affine(&next, world()).encode()),
        (BIN_RENDER, picture.encode()),
        (MAP_BEV, picture.encode()),
        (LATENCY, super::bin_latency().encode()),
        (DIAGNOSTICS, super::diagnostics().encode()),
        (
            LEFT_IMAGE,
            image_from_rgb(&rgb(k.width, k.height), Header::new(STAMP, "left")).encode(),
        ),
        (
            LEFT_INFO,
            camera_info(k, 0.0, Header::new(STAMP, "left")).encode(),
        ),
    ];
    let parts: Vec<Vec<u8>> = samples
        .iter()
        .map(|(t, p)| [&[*t][..], p].concat())
        .collect();
    let parts: Vec<&[u8]> = parts.iter().map(Vec::as_slice).collect();
    seeds.put("view_topics", "stream", &join_frames(&parts))?;
    seeds.put("view_topics", "snapshot", &snapshot)?;
    Ok(())
}

/// A camera-info YAML file as ROS `camera_calibration` writes it.
fn camera_yaml(info: &CameraInfo) -> String {
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!(
        "image_width: {}\nimage_height: {}\ncamera_name: {}\n\
         camera_matrix:\n  rows: 3\n  cols: 3\n  data: [{}]\n\
         distortion_model: {}\n\
         distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [{}]\n\
         rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [{}]\n\
         projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{}]\n",
        info.width,
        info.height,
        info.header.frame_id,
        list(&info.k),
        info.distortion_model,
        list(&info.d),
        list(&info.r),
        list(&info.p),
    )
}
