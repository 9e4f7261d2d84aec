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

use drive_support::{Collector, Drive, Player, RunningNode};
use glam::DVec3;
use model::frame::{DepthMap, Rgb8Image, RgbImage, StereoFrame, StereoRig};
use model::metrics::{depth_errors, DepthFilter};
use node::msg::compressed::{compressed_image, Compression};
use node::msg::gaussians::gaussians_from_cloud;
use node::msg::geometry_msgs::PoseStamped;
use node::msg::image::camera_info;
use node::msg::image::{image_from_rgb, image_with_encoding};
use node::msg::pose::pose_from_affine;
use node::msg::sensor_msgs::CameraInfo;
use node::msg::sensor_msgs::PointCloud2;
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::pipeline::worker::RenderWith;
use node::rectify::{CameraModel, RemapTable};
use node::service::{Keys, NodeConfig, NodeSummary};
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
struct RawRig {
    infos: [CameraInfo; 2],
    distort: [RemapTable; 2],
}

impl RawRig {
    /// `rig`'s cameras behind `plumb_bob` lenses, rotated by +-0.5 degrees about y before
    /// rectification, their raw focal lengths 3% longer than the rectified ones.
    fn behind_lenses(rig: &StereoRig) -> Self {
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
    fn raw(&self, side: usize, img: &RgbImage) -> RgbImage {
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
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        queue_capacity: 64,
        renders: RenderWith::Off,
        method: "sgm".into(),
        ..NodeConfig::default()
    })
    .await;
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
