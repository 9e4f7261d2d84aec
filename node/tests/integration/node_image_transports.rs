//! The images a robot's cameras publish, through the node: a generated drive sent as
//! image_transport's JPEG `CompressedImage` pairs (quality 95, compressed_image_transport's
//! default) on `left/image/compressed` and `right/image/compressed`, as Bayer `bayer_rggb8`
//! images, and by a driver that publishes raw and compressed images of every frame. Each
//! gives every bin of the drive, and the JPEG drive's bin maps hold about as many Gaussians
//! as the same drive sent as `rgb8` (JPEG's loss, stated below and printed).

use crate::drive_support;

use drive_support::{Collector, Drive, Player, RunningNode};
use model::frame::{Rgb8Image, RgbImage, StereoFrame};
use node::msg::compressed::{compressed_image, Compression};
use node::msg::geometry_msgs::PoseStamped;
use node::msg::image::{image_from_rgb, image_with_encoding};
use node::msg::pose::pose_from_affine;
use node::msg::sensor_msgs::PointCloud2;
use node::msg::std_msgs::Header;
use node::msg::Message;
use node::pipeline::worker::RenderWith;
use node::service::{Keys, NodeConfig, NodeSummary};

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

/// Runs `drive` through a fresh node with its images sent as `send`: the summary and the
/// Gaussian count of each bin map.
async fn run(tag: &str, drive: &Drive, send: Send) -> (NodeSummary, Vec<u32>) {
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
    player.camera_infos(&drive.rig, drive.frames[0].0).await;
    for (stamp, frame) in &drive.frames {
        let StereoFrame {
            left,
            right,
            left_to_world,
            ..
        } = frame;
        let header = |id: &str| Header::new(*stamp, id);
        put_image(&player, &keys, send, header("left"), left, false).await;
        put_image(&player, &keys, send, header("right"), right, true).await;
        let pose: PoseStamped = pose_from_affine(left_to_world, header("world"));
        player.put(keys.pose(), pose.encode()).await;
    }
    let opened = drive.bins_opened(8.0);
    assert!(
        outputs.wait_count(&keys.bin_map(), opened).await,
        "{send:?}: every bin"
    );
    let summary = node.stop().await;
    let counts = outputs
        .decoded::<PointCloud2>(&keys.bin_map())
        .iter()
        .map(|c| c.width * c.height)
        .collect();
    (summary, counts)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jpeg_bayer_and_doubled_transports_give_every_bin() {
    let drive = Drive::small("transports");
    let opened = drive.bins_opened(8.0) as u64;
    let (raw, raw_counts) = run("tr_rgb8", &drive, Send::Rgb8).await;
    let (jpeg, jpeg_counts) = run("tr_jpeg", &drive, Send::Jpeg(95)).await;
    let (bayer, bayer_counts) = run("tr_bayer", &drive, Send::Bayer).await;
    let (both, both_counts) = run("tr_both", &drive, Send::Both).await;
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
    let ratio = |counts: &[u32]| {
        counts.iter().map(|&c| c as f64).sum::<f64>()
            / raw_counts.iter().map(|&c| c as f64).sum::<f64>()
    };
    println!(
        "Gaussians per drive against rgb8: JPEG q95 {:.3}x, bayer_rggb8 {:.3}x ({} bins each)",
        ratio(&jpeg_counts),
        ratio(&bayer_counts),
        opened
    );
    for (name, counts) in [("jpeg", &jpeg_counts), ("bayer", &bayer_counts)] {
        assert!(
            (0.8..1.25).contains(&ratio(counts)),
            "{name}: {counts:?} vs {raw_counts:?}"
        );
    }
}
