//! Wire messages: round trips, conversions to and from the project's types, and the REP 2011
//! type hashes against the values ROS 2 Jazzy publishes.

use crate::msg_support;

use glam::DVec3;
use model::frame::RgbImage;
use msg_support::{far_pose, gaussians, samples, FAR};
use node::msg::gaussians::{cloud_from_gaussians, gaussians_from_cloud};
use node::msg::geometry_msgs::PoseStamped;
use node::msg::image::{
    image_from_rgb, intrinsics_from_camera_info, rgb8_from_image, rgb_from_image,
};
use node::msg::latency::{BinLatency, Diagnostics};
use node::msg::pose::affine_from_pose;
use node::msg::sensor_msgs::{datatype, CameraInfo, Image, PointCloud2};
use node::msg::std_msgs::Header;
use node::msg::{type_hash, ConvertError, DecodeError, Message, MessageKind};

#[test]
fn every_sample_round_trips_through_cdr() {
    let s = samples();
    assert_eq!(Image::decode(&s.image.encode()).unwrap(), s.image);
    assert_eq!(
        CameraInfo::decode(&s.camera_info.encode()).unwrap(),
        s.camera_info
    );
    assert_eq!(PoseStamped::decode(&s.pose.encode()).unwrap(), s.pose);
    assert_eq!(PointCloud2::decode(&s.cloud.encode()).unwrap(), s.cloud);
    assert_eq!(BinLatency::decode(&s.latency.encode()).unwrap(), s.latency);
    assert_eq!(
        Diagnostics::decode(&s.diagnostics.encode()).unwrap(),
        s.diagnostics
    );
    // BinLatency: u64 + 6 i64 + u32 (+4 pad) + 2 u64, then 3 u8 (+1 pad) + u32 + 2 f64,
    // after the 4-byte header; version 2 appends 5 i64, version 3 a string (u32 length,
    // the 13 bytes of "tiny-scale0.5" and a NUL), version 4 an i64 (after 6 bytes of
    // padding to its alignment).
    let v4 = s.latency.encode();
    let point = 4 + 14;
    let fused = 6 + 8;
    assert_eq!(
        v4.len(),
        4 + 8 + 48 + 8 + 16 + 4 + 4 + 16 + 40 + point + fused
    );
    // Older payloads (recordings from before the stage split, the operating point or the
    // fusion stamp) are version 4 cut short: they decode with what they lack empty; a
    // payload ending inside the appended fields is truncated.
    let v3 = v4[..v4.len() - fused].to_vec();
    let v3_decoded = BinLatency {
        map_fused_ns: 0,
        ..s.latency.clone()
    };
    assert_eq!(BinLatency::decode(&v3).unwrap(), v3_decoded);
    for cut in [1, 7, 8, 13] {
        assert!(
            BinLatency::decode(&v4[..v4.len() - cut]).is_err(),
            "cut {cut} of version 4"
        );
    }
    let v2 = BinLatency {
        operating_point: String::new(),
        ..v3_decoded
    };
    assert_eq!(BinLatency::decode(&v3[..v3.len() - point]).unwrap(), v2);
    let v1 = BinLatency {
        base_end_ns: 0,
        pseudo_render_end_ns: 0,
        enhance_end_ns: 0,
        plus_end_ns: 0,
        fuse_end_ns: 0,
        ..v2
    };
    assert_eq!(
        BinLatency::decode(&v3[..v3.len() - point - 40]).unwrap(),
        v1
    );
    for cut in [point + 32, point + 8, point + 1, point - 1, 5, 1] {
        assert!(
            BinLatency::decode(&v3[..v3.len() - cut]).is_err(),
            "cut {cut}"
        );
    }
}

#[test]
fn bad_strings_and_bools_are_typed_errors() {
    let mut b = Header::new(0, "map").encode();
    b[19] = b'x'; // the NUL
    assert!(matches!(
        Header::decode(&b),
        Err(DecodeError::MissingNul { .. })
    ));
    b[19] = 0;
    b[16] = 0xff; // 'm' -> invalid UTF-8
    assert!(matches!(
        Header::decode(&b),
        Err(DecodeError::InvalidUtf8 { at: 12, .. })
    ));
    let mut c = samples().cloud.encode();
    let last = c.len() - 1;
    c[last] = 2; // is_dense
    assert!(matches!(
        PointCloud2::decode(&c),
        Err(DecodeError::InvalidBool {
            value: 2,
            what: "is_dense",
            ..
        })
    ));
}

#[test]
fn images_convert_in_rgb8_bgr8_and_mono8() {
    let mut img = RgbImage::new(2, 1);
    img.data = vec![0.0, 0.5, 1.0, 0.2, 0.4, 0.6];
    let msg = image_from_rgb(&img, Header::new(5, "cam"));
    assert_eq!((msg.encoding.as_str(), msg.step), ("rgb8", 6));
    assert_eq!(msg.data, vec![0, 128, 255, 51, 102, 153]);
    let back = rgb_from_image(&msg).unwrap();
    assert!(back
        .data
        .iter()
        .zip(&img.data)
        .all(|(a, b)| (a - b).abs() <= 0.51 / 255.0));

    // bgr8 with 2 bytes of row padding: channels swapped, padding skipped.
    let bgr = Image {
        encoding: "bgr8".to_owned(),
        step: 8,
        data: vec![255, 128, 0, 153, 102, 51, 9, 9],
        ..msg.clone()
    };
    assert_eq!(rgb_from_image(&bgr).unwrap().to_rgb8(), msg.data);
    let mono = Image {
        encoding: "mono8".to_owned(),
        step: 2,
        data: vec![10, 200],
        ..msg.clone()
    };
    assert_eq!(
        rgb_from_image(&mono).unwrap().to_rgb8(),
        vec![10, 10, 10, 200, 200, 200]
    );

    // As packed bytes (how the node keeps an input image): the same pixels, and an rgb8
    // message's data as it is.
    for m in [&msg, &bgr, &mono] {
        let packed = rgb8_from_image(m.clone()).unwrap();
        assert_eq!((packed.width, packed.height), (2, 1));
        assert_eq!(packed.to_rgb(), rgb_from_image(m).unwrap());
    }
    assert_eq!(rgb8_from_image(msg.clone()).unwrap().data, msg.data);
    let short = Image {
        step: 5,
        ..msg.clone()
    };
    assert_eq!(
        rgb8_from_image(short.clone()).unwrap_err(),
        rgb_from_image(&short).unwrap_err()
    );

    let err = rgb_from_image(&Image {
        encoding: "16UC1".to_owned(),
        ..msg.clone()
    });
    assert_eq!(
        err.unwrap_err(),
        ConvertError::UnsupportedEncoding("16UC1".to_owned())
    );
    let short_step = Image {
        step: 5,
        data: vec![0; 5],
        ..msg.clone()
    };
    assert!(matches!(
        rgb_from_image(&short_step),
        Err(ConvertError::ImageSize { min_step: 6, .. })
    ));
    let short_data = Image {
        data: vec![0; 5],
        ..msg
    };
    assert!(matches!(
        rgb_from_image(&short_data),
        Err(ConvertError::ImageSize { len: 5, .. })
    ));
}

#[test]
fn camera_info_carries_the_baseline_in_p() {
    let info = samples().camera_info;
    assert_eq!(
        info.k,
        [552.5, 0.0, 682.0, 0.0, 551.25, 238.75, 0.0, 0.0, 1.0]
    );
    assert_eq!(info.p[3], -552.5 * 0.6);
    assert_eq!((info.width, info.height, info.d.len()), (1408, 376, 5));
    let (k, baseline) = intrinsics_from_camera_info(&info).unwrap();
    assert_eq!(
        (k.fx, k.fy, k.cx, k.cy, k.width),
        (552.5, 551.25, 682.0, 238.75, 1408)
    );
    assert!((baseline - 0.6).abs() < 1e-15);
    let mut bad = info.clone();
    bad.p[0] = 0.0;
    assert!(matches!(
        intrinsics_from_camera_info(&bad),
        Err(ConvertError::BadFocal { .. })
    ));
    bad.p[0] = f64::NAN;
    assert_eq!(
        intrinsics_from_camera_info(&bad).unwrap_err(),
        ConvertError::NonFinite("p[0]")
    );
}

#[test]
fn poses_keep_millimetres_100_km_out_and_refuse_non_rotations() {
    let t = far_pose();
    let back = affine_from_pose(&PoseStamped::decode(&samples().pose.encode()).unwrap()).unwrap();
    assert_eq!(back.translation, FAR);
    assert!(back.matrix3.abs_diff_eq(t.matrix3, 1e-12));

    let mut p = samples().pose;
    p.pose.orientation.w *= 1.01;
    assert!(matches!(
        affine_from_pose(&p),
        Err(ConvertError::NonUnitQuaternion { .. })
    ));
    let mut p = samples().pose;
    p.pose.position.y = f64::INFINITY;
    assert_eq!(
        affine_from_pose(&p).unwrap_err(),
        ConvertError::NonFinite("position.y")
    );
}

#[test]
fn gaussians_round_trip_through_a_bin_frame_cloud() {
    let set = gaussians();
    let cloud = PointCloud2::decode(&samples().cloud.encode()).unwrap();
    assert_eq!(
        (cloud.point_step, cloud.row_step, cloud.width),
        (64, 192, 3)
    );
    assert_eq!(cloud.header.frame_id, "bin_7");
    let names: Vec<_> = cloud.fields.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names[..4], ["x", "y", "z", "f_dc_0"]);
    assert_eq!(names[14..], ["confidence", "rgb"]);
    // Stored values follow the PLY convention: opacity 0.2 -> logit, rot_0 = w.
    let f32_at = |i: usize, off: usize| {
        f32::from_le_bytes(
            cloud.data[64 * i + off..64 * i + off + 4]
                .try_into()
                .unwrap(),
        )
    };
    assert!((f32_at(0, 24) - (0.2f64 / 0.8).ln() as f32).abs() < 1e-6);
    assert!((f32_at(0, 40) - set.rotations[0].w).abs() < 1e-7);

    let back = gaussians_from_cloud(&cloud, DVec3::ZERO).unwrap();
    assert_eq!(back.means, set.means);
    assert_eq!(back.log_scales, set.log_scales);
    assert_eq!(back.rotations, set.rotations);
    for i in 0..set.len() {
        assert!((back.opacities[i] - set.opacities[i]).abs() < 1e-6);
        assert!(back.colors[i].abs_diff_eq(set.colors[i], 1e-6));
        assert_eq!(back.confidences[i], set.confidences[i]);
    }
}

#[test]
fn clouds_without_rgb_as_written_before_it_decode_the_same() {
    for cloud in [samples().cloud, samples().world_cloud] {
        let step = cloud.point_step as usize;
        let mut old = cloud.clone();
        old.fields.retain(|f| f.name != "rgb");
        old.point_step -= 4;
        old.row_step = old.point_step * old.width;
        old.data = cloud
            .data
            .chunks_exact(step)
            .flat_map(|r| r[..step - 4].to_vec())
            .collect();
        let old = PointCloud2::decode(&old.encode()).unwrap();
        assert_eq!(old.point_step, if step == 64 { 60 } else { 72 });
        assert_eq!(
            gaussians_from_cloud(&old, FAR).unwrap(),
            gaussians_from_cloud(&cloud, FAR).unwrap()
        );
    }
}

#[test]
fn world_clouds_store_f64_positions_exact_100_km_out() {
    let set = gaussians();
    let cloud = samples().world_cloud;
    assert_eq!(cloud.point_step, 76);
    assert_eq!(cloud.fields[0].datatype, datatype::FLOAT64);
    let x0 = f64::from_le_bytes(cloud.data[0..8].try_into().unwrap());
    assert_eq!(x0, FAR.x + set.means[0].x as f64);
    // Back, relative to the same origin: bit-exact means.
    let back = gaussians_from_cloud(&cloud, FAR).unwrap();
    assert_eq!(back.means, set.means);
    // World positions in f32 instead would be off by millimetres.
    let f32_err = set
        .means
        .iter()
        .flat_map(|m| (FAR + m.as_dvec3()).to_array())
        .map(|w| (w as f32 as f64 - w).abs())
        .fold(0.0, f64::max);
    println!("largest f32 world-position error 100 km out: {f32_err} m");
    assert!(f32_err > 1e-3, "f32 error {f32_err}");
}

#[test]
fn malformed_clouds_are_typed_errors() {
    let good = samples().cloud;
    let mut c = good.clone();
    c.fields.retain(|f| f.name != "opacity");
    assert_eq!(
        gaussians_from_cloud(&c, DVec3::ZERO).unwrap_err(),
        ConvertError::MissingField("opacity")
    );
    let mut c = good.clone();
    c.fields[5].datatype = datatype::UINT16;
    assert!(matches!(
        gaussians_from_cloud(&c, DVec3::ZERO),
        Err(ConvertError::BadField { .. })
    ));
    let mut c = good.clone();
    c.fields[14].offset = 62; // 4 bytes from 62 pass the 64-byte record
    assert!(matches!(
        gaussians_from_cloud(&c, DVec3::ZERO),
        Err(ConvertError::BadField { .. })
    ));
    let mut c = good.clone();
    c.data.pop();
    assert!(matches!(
        gaussians_from_cloud(&c, DVec3::ZERO),
        Err(ConvertError::CloudSize { .. })
    ));
    let mut c = good.clone();
    c.width = u32::MAX;
    assert!(matches!(
        gaussians_from_cloud(&c, DVec3::ZERO),
        Err(ConvertError::CloudSize { .. })
    ));
    // Without confidence every Gaussian is fully trusted.
    let mut c = good;
    c.fields.retain(|f| f.name != "confidence");
    let set = gaussians_from_cloud(&c, DVec3::ZERO).unwrap();
    assert_eq!(set.confidences, vec![1.0; 3]);
    let mut uneven = gaussians();
    uneven.opacities.pop();
    assert!(matches!(
        cloud_from_gaussians(&uneven, Header::default(), None),
        Err(ConvertError::LengthMismatch(_))
    ));
}

/// Jazzy's values, as `ros2 topic info -v` prints them and rosidl's golden-hash tests and
/// client libraries list them (e.g. the image_publisher docs of image_pipeline for Image).
const PUBLISHED: [(MessageKind, &str); 20] = [
    (
        MessageKind::Time,
        "b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
    ),
    (
        MessageKind::Header,
        "f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
    ),
    (
        MessageKind::Image,
        "d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47",
    ),
    (
        MessageKind::CameraInfo,
        "b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275",
    ),
    // rosidl_generator_c's sensor_msgs__msg__CompressedImage__TYPE_HASH.
    (
        MessageKind::CompressedImage,
        "15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a",
    ),
    (
        MessageKind::RegionOfInterest,
        "ad16bcba5f9131dcdba6fbded19f726f5440e3c513b4fb586dd3027eeed8abb1",
    ),
    (
        MessageKind::PoseStamped,
        "10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
    ),
    (
        MessageKind::Pose,
        "d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa",
    ),
    (
        MessageKind::Point,
        "6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881",
    ),
    (
        MessageKind::PointCloud2,
        "9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5",
    ),
    (
        MessageKind::PointField,
        "5c6a4750728c2bcfbbf7037225b20b02d4429634732146b742dee1726637ef01",
    ),
    // geometry_msgs' installed type description (share/geometry_msgs/msg/TransformStamped.json).
    (
        MessageKind::TransformStamped,
        "0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206",
    ),
    (
        MessageKind::Transform,
        "beb83fbe698636351461f6f35d1abb20010c43d55374d81bd041f1ba2581fddc",
    ),
    (
        MessageKind::Vector3,
        "cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d",
    ),
    // The generated C headers of geometry_msgs and nav_msgs (`*__struct.h`, `*__TYPE_HASH`)
    // as micro-ROS ships them for a distribution with type hashes.
    (
        MessageKind::PoseWithCovariance,
        "9a7c0fd234b7f45c6098745ecccd773ca1085670e64107135397aee31c02e1bb",
    ),
    (
        MessageKind::Twist,
        "9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a",
    ),
    (
        MessageKind::TwistWithCovariance,
        "49f574f033f095d8b6cd1beaca5ca7925e296e84af1716d16c89d38b059c8c18",
    ),
    (
        MessageKind::Odometry,
        "3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
    ),
    (
        MessageKind::Path,
        "1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b",
    ),
    // rmw_zenoh's tests key /tf with this hash.
    (
        MessageKind::TfMessage,
        "e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    ),
];

#[test]
fn type_hashes_match_the_published_jazzy_values() {
    for (kind, hex) in PUBLISHED {
        assert_eq!(
            type_hash(kind),
            format!("RIHS01_{hex}"),
            "{}",
            kind.ros_name()
        );
    }
    for (i, kind) in MessageKind::ALL.into_iter().enumerate() {
        assert_eq!(kind as usize, i);
        assert_eq!(MessageKind::from_ros_name(kind.ros_name()), Some(kind));
        let h = type_hash(kind);
        assert!(h.len() == 71 && h.starts_with("RIHS01_"), "{h}");
    }
    assert_eq!(
        MessageKind::Image.dds_type_name(),
        "sensor_msgs::msg::dds_::Image_"
    );
    assert_eq!(
        MessageKind::BinLatency.dds_type_name(),
        "stereosplat_msgs::msg::dds_::BinLatency_"
    );
}
