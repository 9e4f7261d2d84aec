//! The images a robot's cameras publish, through the node: a generated drive sent as
//! image_transport's JPEG `CompressedImage` pairs (quality 95, compressed_image_transport's
//! default) on `left/image/compressed` and `right/image/compressed`, as Bayer `bayer_rggb8`
//! images, and by a driver that publishes raw and compressed images of every frame. Each
//! gives every bin of the drive, and the JPEG drive's bin maps hold about as many Gaussians
//! as the same drive sent as `rgb8`. And the same drive as a driver of raw, distorted
//! cameras publishes it (`plumb_bob` lenses and rectification rotations of half a degree,
//! with the full camera infos): rectified in the node, its bin maps render the depth of the
//! drive sent rectified within an AbsRel of 0.1.
//!
//! Measured (SGM, 272x72, 3 bins; printed by the tests): against the `rgb8` drive, JPEG q95
//! gives 0.84x the Gaussians and a depth AbsRel of 0.115, `bayer_rggb8` 0.95x and 0.085;
//! the raw drive rectified in the node 0.074 mean, 0.096 worst: the same order as any
//! resampling of the images costs SGM at this size.

use crate::drive_support;

use drive_support::{sgm_config, Collector, Drive, Player, RunningNode};
use glam::DVec3;
use model::bins::{make_bins, BinConfig, BinLayout};
use model::frame::{DepthMap, Rgb8Image, RgbImage, StereoFrame, StereoRig};
use model::metrics::{depth_errors, DepthFilter};
use node::msg::compressed::{compressed_image, Compression};
use node::msg::gaussians::gaussians_from_cloud;
use node::msg::geometry_msgs::PoseStamped;
use node::msg::image::camera_info;
use node::msg::image::{image_from_rgb, image_with_encoding};
use node::msg::pose::pose_from_affine;
use node::msg::sensor_msgs::PointCloud2;
use node::msg::sensor_msgs::{CameraInfo, CompressedImage};
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::rectify::{CameraModel, RemapTable};
use node::service::NodeSummary;
use node::transport::Keys;
use renderer::{Camera, GaussianSet, Intrinsics, Raster, RenderSettings};

/// How the player sends each frame's images.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Send {
    /// `rgb8` on the raw topics.
    Rgb8,
    /// JPEG of this quality on the compressed topics.
    Jpeg(u8),
    /// `bayer_rggb8` on the raw topics.
    Bayer,
    /// `rgb8` on the raw topics and JPEG on the compressed ones, raw first.
    Both,
}

fn rgb8(img: &RgbImage) -> Rgb8Image {
    Rgb8Image {
        width: img.width,
        height: img.height,
        data: img.to_rgb8(),
    }
}

/// Publishes one image of `frame` on the left (`right` false) or right camera's keys.
async fn put_image(
    player: &Player,
    keys: &Keys,
    send: Send,
    header: Header,
    img: &RgbImage,
    right: bool,
) {
    let (raw, compressed) = match right {
        false => (keys.left_image(), keys.left_compressed()),
        true => (keys.right_image(), keys.right_compressed()),
    };
    let jpeg = |quality| {
        compressed_image(&rgb8(img), Compression::Jpeg { quality }, header.clone())
            .expect("encodes")
            .encode()
    };
    match send {
        Send::Rgb8 => player.put(raw, image_from_rgb(img, header).encode()).await,
        Send::Jpeg(q) => player.put(compressed, jpeg(q)).await,
        Send::Bayer => {
            let msg = image_with_encoding(&rgb8(img), "bayer_rggb8", header).expect("mosaics");
            player.put(raw, msg.encode()).await;
        }
        Send::Both => {
            player
                .put(raw, image_from_rgb(img, header.clone()).encode())
                .await;
            player.put(compressed, jpeg(95)).await;
        }
    }
}

/// A stereo rig of raw cameras: each camera's info and the table that makes its raw image
/// from a rectified one.
pub(crate) struct RawRig {
    /// Each camera's info (K, D, R, P), left first.
    pub(crate) infos: [CameraInfo; 2],
    distort: [RemapTable; 2],
}

impl RawRig {
    /// `rig`'s cameras behind `plumb_bob` lenses, rotated by +-0.5 degrees about y before
    /// rectification, their raw focal lengths 3% longer than the rectified ones.
    pub(crate) fn behind_lenses(rig: &StereoRig) -> Self {
        let k = &rig.intrinsics;
        let info = |side: f64, tx: f64| {
            let mut info = camera_info(k, 0.0, Header::new(0, "camera"));
            let (fx, fy) = (k.fx as f64 * 1.03, k.fy as f64 * 1.03);
            info.k = [fx, 0.0, k.cx as f64, 0.0, fy, k.cy as f64, 0.0, 0.0, 1.0];
            info.d = vec![-0.12, 0.02, 0.0004, -0.0003, 0.0];
            let r = glam::DMat3::from_rotation_y(side * 0.5f64.to_radians());
            // CameraInfo's R is row major.
            info.r = r.transpose().to_cols_array();
            info.p[3] = tx;
            info
        };
        let infos = [info(1.0, 0.0), info(-1.0, -(k.fx as f64) * rig.baseline)];
        let distort = infos
            .each_ref()
            .map(|i| RemapTable::distort(&CameraModel::from_camera_info(i).expect("a lens")));
        Self { infos, distort }
    }

    /// `img` as camera `side` (0 left, 1 right) takes it.
    pub(crate) fn raw(&self, side: usize, img: &RgbImage) -> RgbImage {
        let raw = self.distort[side]
            .remap(&rgb8(img))
            .expect("the camera's size");
        RgbImage::from_rgb8(raw.width, raw.height, &raw.data)
    }
}

/// Runs `drive` through a fresh node (SGM, renders off) with its images sent as `send`,
/// taken by the cameras of `raw` when given: the summary and the bin maps.
async fn run_maps(
    tag: &str,
    drive: &Drive,
    send: Send,
    raw: Option<&RawRig>,
) -> (NodeSummary, Vec<GaussianSet>) {
    let keys = Keys::new(tag);
    let node = RunningNode::start(sgm_config(&keys)).await;
    let outputs = Collector::connect(&node, &[keys.bin_map()]).await;
    let player = Player::connect(&node).await;
    let put_infos = |stamp: i64| {
        let (player, keys) = (&player, &keys);
        async move {
            if let Some(raw) = raw {
                for (info, key) in raw.infos.iter().zip([keys.left_info(), keys.right_info()]) {
                    let mut info = info.clone();
                    info.header = Header::new(stamp, "camera");
                    player.put(key, info.encode()).await;
                }
            }
        }
    };
    match raw {
        Some(_) => put_infos(drive.frames[0].0).await,
        None => player.camera_infos(&drive.rig, drive.frames[0].0).await,
    }
    for (stamp, frame) in &drive.frames {
        let StereoFrame {
            left,
            right,
            left_to_world,
            ..
        } = frame;
        let header = |id: &str| Header::new(*stamp, id);
        let (left, right) = match raw {
            Some(r) => (r.raw(0, left), r.raw(1, right)),
            None => (left.clone(), right.clone()),
        };
        put_infos(*stamp).await;
        put_image(&player, &keys, send, header("left"), &left, false).await;
        put_image(&player, &keys, send, header("right"), &right, true).await;
        let pose: PoseStamped = pose_from_affine(left_to_world, header("world"));
        player.put(keys.pose(), pose.encode()).await;
    }
    let opened = drive.bins_opened(8.0);
    assert!(
        outputs.wait_count(&keys.bin_map(), opened).await,
        "{send:?}: every bin"
    );
    let summary = node.stop().await;
    let maps = outputs
        .decoded::<PointCloud2>(&keys.bin_map())
        .iter()
        .map(|c| gaussians_from_cloud(c, DVec3::ZERO).expect("a bin map"))
        .collect();
    (summary, maps)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jpeg_bayer_and_doubled_transports_give_every_bin() {
    let drive = Drive::small("transports");
    let opened = drive.bins_opened(8.0) as u64;
    let (raw, raw_maps) = run_maps("tr_rgb8", &drive, Send::Rgb8, None).await;
    let (jpeg, jpeg_maps) = run_maps("tr_jpeg", &drive, Send::Jpeg(95), None).await;
    let (bayer, bayer_maps) = run_maps("tr_bayer", &drive, Send::Bayer, None).await;
    let (both, both_maps) = run_maps("tr_both", &drive, Send::Both, None).await;
    let counts = |maps: &[GaussianSet]| maps.iter().map(|m| m.len()).collect::<Vec<_>>();
    let (raw_counts, jpeg_counts) = (counts(&raw_maps), counts(&jpeg_maps));
    let (bayer_counts, both_counts) = (counts(&bayer_maps), counts(&both_maps));
    for (name, s) in [
        ("rgb8", &raw),
        ("jpeg", &jpeg),
        ("bayer", &bayer),
        ("both", &both),
    ] {
        assert_eq!(s.bins_published, opened, "{name}: {:?}", s.counters);
        assert_eq!(
            s.counters.sum("bad_message/"),
            0,
            "{name}: {:?}",
            s.counters
        );
    }
    // The doubled driver: the first image of each camera chose its transport (raw), every
    // compressed one was ignored, and the maps are those of the raw drive.
    let frames = drive.frames.len() as u64;
    assert_eq!(both.counters.get("ignored/second_transport"), 2 * frames);
    assert_eq!(both_counts, raw_counts);
    let ratio = |counts: &[usize]| {
        counts.iter().map(|&c| c as f64).sum::<f64>()
            / raw_counts.iter().map(|&c| c as f64).sum::<f64>()
    };
    let k = &drive.rig.intrinsics;
    let (jpeg_rel, _) = depth_abs_rel(&jpeg_maps, &raw_maps, k);
    let (bayer_rel, _) = depth_abs_rel(&bayer_maps, &raw_maps, k);
    println!(
        "against rgb8: JPEG q95 {:.3}x the Gaussians, depth AbsRel {jpeg_rel:.4}; bayer_rggb8 {:.3}x, {bayer_rel:.4} ({} bins each)",
        ratio(&jpeg_counts),
        ratio(&bayer_counts),
        opened
    );
    assert!(jpeg_rel < 0.2 && bayer_rel < 0.2, "{jpeg_rel} {bayer_rel}");
    for (name, counts) in [("jpeg", &jpeg_counts), ("bayer", &bayer_counts)] {
        assert!(
            (0.8..1.25).contains(&ratio(counts)),
            "{name}: {counts:?} vs {raw_counts:?}"
        );
    }
}

/// The depth `set` renders from the bin's input view.
fn depth(set: &GaussianSet, k: &Intrinsics) -> DepthMap {
    let out = Raster::Cpu
        .render(set, &Camera::identity(*k), &RenderSettings::default())
        .expect("the CPU renders");
    DepthMap {
        width: out.width,
        height: out.height,
        data: out.depth,
    }
}

/// The depth AbsRel of each map of `maps` against the same bin's map in `truth`, both
/// rendered from the bin's input view: the mean and the worst.
fn depth_abs_rel(maps: &[GaussianSet], truth: &[GaussianSet], k: &Intrinsics) -> (f64, f64) {
    let rel: Vec<f64> = maps
        .iter()
        .zip(truth)
        .map(|(made, given)| {
            depth_errors(&depth(made, k), &depth(given, k), &DepthFilter::default())
                .expect("the reference map covers pixels")
                .abs_rel
        })
        .collect();
    let worst = rel.iter().copied().fold(0.0, f64::max);
    (rel.iter().sum::<f64>() / rel.len() as f64, worst)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn raw_distorted_cameras_are_rectified_in_the_node() {
    let drive = Drive::small("rectified_in_node");
    let opened = drive.bins_opened(8.0) as u64;
    let raw_rig = RawRig::behind_lenses(&drive.rig);
    let (rectified, truth) = run_maps("rect_given", &drive, Send::Rgb8, None).await;
    let (raw, maps) = run_maps("rect_node", &drive, Send::Rgb8, Some(&raw_rig)).await;
    for s in [&rectified, &raw] {
        assert_eq!(s.bins_published, opened, "{:?}", s.counters);
        assert_eq!(s.counters.sum("bad_message/"), 0, "{:?}", s.counters);
        assert_eq!(s.counters.sum("refused/"), 0, "{:?}", s.counters);
    }
    let (mean, worst) = depth_abs_rel(&maps, &truth, &drive.rig.intrinsics);
    println!(
        "raw distorted drive rectified in the node: depth AbsRel against the drive sent rectified {mean:.4} mean, {worst:.4} worst ({opened} bins)"
    );
    assert!(worst < 0.1, "AbsRel {worst}");
}

/// `msg`'s JPEG frame header (SOF0) rewritten to claim `side` x `side` pixels.
fn claiming(mut msg: CompressedImage, side: u16) -> CompressedImage {
    let sof = msg
        .data
        .windows(2)
        .position(|w| w == [0xff, 0xc0])
        .expect("a baseline JPEG");
    // Marker, length (2), precision (1), then height and width.
    msg.data[sof + 5..sof + 9].copy_from_slice(&[side.to_be_bytes(), side.to_be_bytes()].concat());
    msg
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hostile_images_and_calibrations_are_counted_and_the_drive_still_comes_out() {
    let drive = Drive::small("hostile_images");
    let keys = Keys::new("hostile_images");
    let node = RunningNode::start(sgm_config(&keys)).await;
    let outputs = Collector::connect_truncated(&node, &[keys.bin_map()], 1 << 12).await;
    let player = Player::connect(&node).await;
    let (first, frame) = &drive.frames[0];
    let header = |id: &str| Header::new(*first, id);
    let jpeg = |img: &RgbImage, id: &str| {
        compressed_image(&rgb8(img), Compression::Jpeg { quality: 95 }, header(id)).unwrap()
    };
    // A JPEG bomb on each camera: 60000x60000 claimed in a few kilobytes.
    for (key, img) in [
        (keys.left_compressed(), &frame.left),
        (keys.right_compressed(), &frame.right),
    ] {
        player
            .put(key, claiming(jpeg(img, "cam"), 60000).encode())
            .await;
    }
    // A Bayer image one pixel tall.
    let strip = Rgb8Image {
        width: 5,
        height: 1,
        data: vec![128; 15],
    };
    let bayer = image_with_encoding(&strip, "bayer_rggb8", header("left")).unwrap();
    player.put(keys.left_image(), bayer.encode()).await;
    // A right camera info with a NaN distortion coefficient.
    let mut nan = camera_info(&drive.rig.intrinsics, drive.rig.baseline, header("right"));
    nan.d[1] = f64::NAN;
    player.put(keys.right_info(), nan.encode()).await;
    player.camera_infos(&drive.rig, *first).await;
    // The drive as JPEG pairs, its first left image cut off before its end-of-image marker:
    // its frame cannot open a bin, the next one does.
    for (i, (stamp, frame)) in drive.frames.iter().enumerate() {
        let header = |id: &str| Header::new(*stamp, id);
        let mut left = jpeg(&frame.left, "left");
        left.header = header("left");
        if i == 0 {
            left.data.truncate(left.data.len() / 2);
        }
        player.put(keys.left_compressed(), left.encode()).await;
        put_image(
            &player,
            &keys,
            Send::Jpeg(95),
            header("right"),
            &frame.right,
            true,
        )
        .await;
        let pose: PoseStamped = pose_from_affine(&frame.left_to_world, header("world"));
        player.put(keys.pose(), pose.encode()).await;
    }
    let poses = &drive.poses()[1..];
    let config = BinConfig {
        length_m: 8.0,
        layout: BinLayout::Consecutive,
    };
    let opened = make_bins(poses, &config).len() + 1;
    assert!(
        outputs.wait_count(&keys.bin_map(), opened).await,
        "every bin of the drive"
    );
    assert!(node.is_running());
    let summary = node.stop().await;
    let c = &summary.counters;
    println!("hostile inputs counted: {c:?}");
    assert_eq!(summary.bins_published, opened as u64, "{c:?}");
    assert_eq!(c.get("refused/image_too_large"), 2, "{c:?}");
    assert_eq!(
        c.get("bad_message/left_image_compressed"),
        2,
        "the bomb and the cut JPEG"
    );
    assert_eq!(c.get("bad_message/right_image_compressed"), 1, "the bomb");
    assert_eq!(
        c.get("bad_message/left_image"),
        1,
        "the one-row Bayer image"
    );
    assert_eq!(
        c.get("bad_message/right_camera_info"),
        1,
        "the NaN distortion"
    );
    assert_eq!(c.get("refused/camera_info"), 1, "{c:?}");
}
