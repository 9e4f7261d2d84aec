//! JPEG and PNG compressed images of generated frames decoded back (PSNR floors for JPEG,
//! exact for PNG), headers read before decoding, and files claiming 60000x60000 pixels,
//! cut off, corrupt, empty, grey, 16-bit and 1x1.

use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder};

use super::*;
use crate::alloc_probe::largest_allocation;
use crate::msg::test_frames::{psnr8, smooth, textured};
use crate::msg::{Message, MessageKind};

fn jpeg(img: &Rgb8Image, quality: u8) -> CompressedImage {
    compressed_image(img, Compression::Jpeg { quality }, Header::new(9, "cam")).unwrap()
}

fn png(img: &Rgb8Image) -> CompressedImage {
    compressed_image(img, Compression::Png, Header::new(9, "cam")).unwrap()
}

/// A message of `data` in format `format`.
fn message(format: &str, data: Vec<u8>) -> CompressedImage {
    CompressedImage {
        header: Header::default(),
        format: format.into(),
        data,
    }
}

fn decode(msg: &CompressedImage) -> Result<Rgb8Image, CompressedError> {
    rgb8_from_compressed(msg, &PixelLimits::default())
}

/// A PNG of `width` x `height` samples of `colour` (`image`'s encoder).
fn png_of(data: &[u8], width: u32, height: u32, colour: ExtendedColorType) -> Vec<u8> {
    let mut out = Vec::new();
    PngEncoder::new(&mut out)
        .write_image(data, width, height, colour)
        .unwrap();
    out
}

/// Where the frame header's height field of a JPEG file is (after SOF's length and
/// precision).
fn jpeg_sof_height_at(data: &[u8]) -> usize {
    let sof = data.windows(2).position(|w| w == [0xff, 0xc0]).unwrap();
    sof + 5
}

#[test]
fn jpeg_decodes_within_a_psnr_floor_of_the_frame() {
    // Measured (the `image` crate's encoder and decoder): textured 96x64 at quality 90
    // 40.3 dB, at 75 35.1 dB; smooth 48.4 and 46.1 dB.
    for (name, img, floors) in [
        ("textured", textured(96, 64), [38.0, 33.0]),
        ("smooth", smooth(96, 64), [46.0, 44.0]),
    ] {
        for (quality, floor) in [90, 75].into_iter().zip(floors) {
            let msg = jpeg(&img, quality);
            assert_eq!(msg.format, "rgb8; jpeg compressed bgr8");
            let header = peek_compressed(&msg.data).unwrap();
            assert_eq!(
                header,
                CompressedHeader {
                    codec: Codec::Jpeg,
                    width: 96,
                    height: 64,
                    channels: 3,
                    bit_depth: 8
                }
            );
            let back = decode(&msg).unwrap();
            assert_eq!(
                (back.width, back.height, back.data.len()),
                (96, 64, 96 * 64 * 3)
            );
            let db = psnr8(&img, &back);
            eprintln!(
                "jpeg q{quality} {name}: {db:.1} dB, {} bytes",
                msg.data.len()
            );
            assert!(db >= floor, "q{quality} {name}: {db:.1} dB");
        }
    }
}

#[test]
fn png_round_trips_exactly() {
    let img = textured(45, 31);
    let msg = png(&img);
    assert_eq!(msg.format, "rgb8; png compressed bgr8");
    let header = peek_compressed(&msg.data).unwrap();
    assert_eq!(
        (
            header.codec,
            header.width,
            header.height,
            header.channels,
            header.bit_depth
        ),
        (Codec::Png, 45, 31, 3, 8)
    );
    assert_eq!(decode(&msg).unwrap(), img);
}

#[test]
fn grey_alpha_and_16_bit_pngs_become_packed_rgb() {
    let (w, h) = (5, 3);
    let grey: Vec<u8> = (0..15).map(|i| i * 17).collect();
    let rgb_of_grey: Vec<u8> = grey.iter().flat_map(|&v| [v; 3]).collect();
    let l8 = png_of(&grey, w, h, ExtendedColorType::L8);
    assert_eq!(peek_compressed(&l8).unwrap().channels, 1);
    assert_eq!(decode(&message("png", l8)).unwrap().data, rgb_of_grey);
    let la8: Vec<u8> = grey.iter().flat_map(|&v| [v, 7]).collect();
    let la8 = png_of(&la8, w, h, ExtendedColorType::La8);
    assert_eq!(peek_compressed(&la8).unwrap().channels, 2);
    assert_eq!(decode(&message("png", la8)).unwrap().data, rgb_of_grey);
    // Alpha dropped, colour kept as it is (not premultiplied).
    let img = textured(w, h);
    let rgba: Vec<u8> = img
        .data
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 3])
        .collect();
    let rgba = png_of(&rgba, w, h, ExtendedColorType::Rgba8);
    assert_eq!(peek_compressed(&rgba).unwrap().channels, 4);
    assert_eq!(decode(&message("png", rgba)).unwrap(), img);
    // 16-bit values (native-endian samples for the encoder) b * 257 come back as b; other
    // values round to the nearest byte: 0x00ff (0.99 * 257) is 1, where v >> 8 would be 0.
    let rgb16: Vec<u8> = img
        .data
        .iter()
        .flat_map(|&b| (b as u16 * 257).to_ne_bytes())
        .collect();
    let rgb16 = png_of(&rgb16, w, h, ExtendedColorType::Rgb16);
    assert_eq!(peek_compressed(&rgb16).unwrap().bit_depth, 16);
    assert_eq!(decode(&message("png", rgb16)).unwrap(), img);
    let l16: Vec<u8> = [0x00ffu16, 0xffff, 0]
        .iter()
        .flat_map(|v| v.to_ne_bytes())
        .collect();
    let l16 = png_of(&l16, 3, 1, ExtendedColorType::L16);
    assert_eq!(
        decode(&message("png", l16)).unwrap().data,
        [1, 1, 1, 255, 255, 255, 0, 0, 0]
    );
}

#[test]
fn grey_jpeg_becomes_grey_rgb() {
    let img = smooth(40, 24);
    let grey: Vec<u8> = img.data.chunks_exact(3).map(|p| p[1]).collect();
    let mut data = Vec::new();
    JpegEncoder::new_with_quality(&mut data, 90)
        .write_image(&grey, 40, 24, ExtendedColorType::L8)
        .unwrap();
    let header = peek_compressed(&data).unwrap();
    assert_eq!((header.channels, header.width, header.height), (1, 40, 24));
    let back = decode(&message("mono8; jpeg compressed mono8", data)).unwrap();
    assert!(back
        .data
        .chunks_exact(3)
        .all(|p| p[0] == p[1] && p[1] == p[2]));
    let want = Rgb8Image {
        data: grey.iter().flat_map(|&v| [v; 3]).collect(),
        ..img
    };
    let db = psnr8(&want, &back);
    assert!(db >= 40.0, "grey jpeg: {db:.1} dB");
}

#[test]
fn one_pixel_images_decode() {
    let img = Rgb8Image {
        width: 1,
        height: 1,
        data: vec![250, 120, 10],
    };
    assert_eq!(decode(&png(&img)).unwrap(), img);
    let back = decode(&jpeg(&img, 95)).unwrap();
    assert_eq!((back.width, back.height), (1, 1));
    for (a, b) in back.data.iter().zip(&img.data) {
        assert!(a.abs_diff(*b) <= 12, "{:?} vs {:?}", back.data, img.data);
    }
}

#[test]
fn a_claim_of_60000_by_60000_is_refused_before_anything_is_allocated() {
    let mut big_jpeg = jpeg(&smooth(16, 8), 90);
    let at = jpeg_sof_height_at(&big_jpeg.data);
    big_jpeg.data[at..at + 4].copy_from_slice(&[0xea, 0x60, 0xea, 0x60]);
    let mut big_png = png(&smooth(16, 8));
    big_png.data[16..24].copy_from_slice(&[0, 0, 0xea, 0x60, 0, 0, 0xea, 0x60]);
    for (msg, codec) in [(big_jpeg, Codec::Jpeg), (big_png, Codec::Png)] {
        let header = peek_compressed(&msg.data).unwrap();
        assert_eq!((header.width, header.height), (60000, 60000));
        let (largest, result) = largest_allocation(|| decode(&msg));
        match result {
            Err(CompressedError::TooLarge {
                codec: c,
                width: 60000,
                height: 60000,
                ..
            }) => assert_eq!(c, codec),
            other => panic!("{codec}: {other:?}"),
        }
        // 60000^2 RGB would be 10.8 GB; nothing but the error's text is allocated.
        assert!(largest < 4096, "{codec}: {largest} bytes allocated");
    }
    // Within the width and height limits but over the pixel count.
    let limits = PixelLimits {
        max_width: 100,
        max_height: 100,
        max_pixels: 99,
    };
    assert!(matches!(
        rgb8_from_compressed(&png(&smooth(10, 10)), &limits),
        Err(CompressedError::TooLarge { .. })
    ));
    assert!(rgb8_from_compressed(&png(&smooth(11, 9)), &limits).is_ok());
}

#[test]
fn cut_off_jpeg_and_png_are_errors_at_every_length() {
    let img = textured(24, 16);
    let whole = jpeg(&img, 90);
    for cut in 0..whole.data.len() {
        let short = message(&whole.format, whole.data[..cut].to_vec());
        assert!(decode(&short).is_err(), "jpeg cut at {cut}");
    }
    // Whatever follows the end marker (zero padding, junk) is left alone.
    for tail in [&[0u8; 7][..], b"\xff\xd8 junk"] {
        let padded = message("jpeg", [&whole.data[..], tail].concat());
        assert_eq!(decode(&padded).unwrap(), decode(&whole).unwrap());
    }
    assert!(matches!(
        decode(&message(
            "jpeg",
            whole.data[..whole.data.len() - 1].to_vec()
        )),
        Err(CompressedError::Unterminated { .. })
    ));
    // PNG: every cut before the closing 12-byte IEND chunk is an error; one inside it has
    // every pixel, and may decode (exactly).
    let file = png(&img);
    let iend = file.data.len() - 12;
    assert_eq!(&file.data[iend + 4..iend + 8], b"IEND");
    for cut in 0..file.data.len() {
        let short = decode(&message("png", file.data[..cut].to_vec()));
        match short {
            Ok(back) if cut >= iend => assert_eq!(back, img),
            Ok(_) => panic!("png cut at {cut} decoded"),
            Err(_) => {}
        }
    }
    // Before the frame header: the header peek says so.
    let msg = jpeg(&smooth(8, 8), 90);
    let at = jpeg_sof_height_at(&msg.data);
    assert!(matches!(
        peek_compressed(&msg.data[..at + 2]),
        Err(CompressedError::Truncated {
            codec: Codec::Jpeg,
            ..
        })
    ));
    let png = png(&smooth(8, 8));
    assert!(matches!(
        peek_compressed(&png.data[..20]),
        Err(CompressedError::Truncated {
            codec: Codec::Png,
            len: 20
        })
    ));
}

#[test]
fn the_end_marker_is_found_through_scans_restarts_and_segments() {
    let soi = [0xff, 0xd8];
    let sos = [0xff, 0xda, 0x00, 0x02];
    // Entropy-coded data with a stuffed 0xff and a restart marker.
    let scan = [0x12, 0xff, 0x00, 0x34, 0xff, 0xd0, 0x56];
    // A table between two scans (as progressive files have) whose bytes hold ff d9.
    let table = [0xff, 0xc4, 0x00, 0x04, 0xff, 0xd9];
    let eoi = [0xff, 0xd9];
    let whole = [
        &soi[..],
        &sos,
        &scan,
        &table,
        &sos,
        &scan,
        &[0xff, 0xff],
        &eoi,
    ]
    .concat();
    assert!(reaches_eoi(&whole));
    for cut in 0..whole.len() - 1 {
        assert!(!reaches_eoi(&whole[..cut]), "cut at {cut}");
    }
}

#[test]
fn garbage_and_empty_data_are_typed_errors() {
    assert!(matches!(
        decode(&message("jpeg", Vec::new())),
        Err(CompressedError::Empty)
    ));
    let noise: Vec<u8> = (0..500u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    match decode(&message("jpeg", noise.clone())) {
        Err(CompressedError::UnknownCodec(magic)) => assert_eq!(magic, noise[..8]),
        other => panic!("{other:?}"),
    }
    // The right magic bytes, then noise.
    let jpeg_noise = [&[0xff, 0xd8, 0xff][..], &noise].concat();
    assert!(decode(&message("jpeg", jpeg_noise)).is_err());
    let png_noise = [&PNG_SIGNATURE[..], &noise].concat();
    assert!(matches!(
        decode(&message("png", png_noise)),
        Err(CompressedError::NoFrameHeader {
            codec: Codec::Png,
            ..
        })
    ));
    // A JPEG that reaches its scan or its end without a frame header.
    for (tail, found) in [
        ([0xff, 0xda], "start of scan"),
        ([0xff, 0xd9], "end of image"),
    ] {
        let data = [&[0xff, 0xd8, 0xff, 0xe0, 0x00, 0x04, 1, 2][..], &tail].concat();
        match peek_compressed(&data) {
            Err(CompressedError::NoFrameHeader { found: f, .. }) => assert_eq!(f, found),
            other => panic!("{other:?}"),
        }
    }
    // A segment length below 2, a zero-height frame, a PNG of width 0.
    let short = [0xff, 0xd8, 0xff, 0xe0, 0x00, 0x01];
    assert!(matches!(
        peek_compressed(&short),
        Err(CompressedError::BadHeader { at: 4, .. })
    ));
    let mut zero = jpeg(&smooth(8, 8), 90).data;
    let at = jpeg_sof_height_at(&zero);
    zero[at..at + 2].copy_from_slice(&[0, 0]);
    assert!(matches!(
        decode(&message("jpeg", zero)),
        Err(CompressedError::BadHeader { .. })
    ));
    let mut zero = png(&smooth(8, 8)).data;
    zero[16..20].copy_from_slice(&[0; 4]);
    assert!(matches!(
        decode(&message("png", zero)),
        Err(CompressedError::BadHeader { at: 16, .. })
    ));
    // Corrupt pixels: every byte after the headers flipped.
    for msg in [jpeg(&textured(24, 16), 90), png(&textured(24, 16))] {
        let mut data = msg.data.clone();
        let (from, to) = (data.len() / 2, data.len() - 2);
        data[from..to].iter_mut().for_each(|b| *b ^= 0x5a);
        let _ = decode(&message("", data));
    }
}

#[test]
fn the_magic_bytes_name_the_codec_whatever_the_format_says() {
    let img = textured(12, 10);
    let mut as_png = jpeg(&img, 90);
    as_png.format = "png".into();
    let back = decode(&as_png).unwrap();
    assert!(psnr8(&img, &back) > 30.0);
    let mut as_jpeg = png(&img);
    as_jpeg.format = "bgr8; jpeg compressed bgr8".into();
    assert_eq!(decode(&as_jpeg).unwrap(), img);
    // A depth image is refused by its format.
    as_jpeg.format = "16UC1; compressedDepth png".into();
    assert!(matches!(decode(&as_jpeg), Err(CompressedError::Depth(_))));
}

#[test]
fn a_frame_header_that_disagrees_with_the_decoder_is_an_error() {
    // A second, larger frame header before the real one: the peek reads the first (4x4),
    // the decoder may use either; it must not decode more than 4x4 pixels.
    let msg = jpeg(&smooth(16, 8), 90);
    let sof = jpeg_sof_height_at(&msg.data) - 5;
    let len = u16::from_be_bytes([msg.data[sof + 2], msg.data[sof + 3]]) as usize;
    let mut fake = msg.data[sof..sof + 2 + len].to_vec();
    fake[5..9].copy_from_slice(&[0, 4, 0, 4]);
    let data = [&msg.data[..sof], &fake, &msg.data[sof..]].concat();
    assert_eq!(
        (
            peek_compressed(&data).unwrap().width,
            peek_compressed(&data).unwrap().height
        ),
        (4, 4)
    );
    match decode(&message("jpeg", data)) {
        Ok(img) => assert_eq!((img.width, img.height), (4, 4)),
        Err(CompressedError::SizeMismatch { .. } | CompressedError::Decode { .. }) => {}
        Err(other) => panic!("{other:?}"),
    }
}

#[test]
fn the_message_round_trips_in_cdr_with_jazzys_type_hash() {
    let msg = jpeg(&smooth(6, 4), 80);
    assert_eq!(CompressedImage::decode(&msg.encode()).unwrap(), msg);
    // rosidl's generated sensor_msgs__msg__CompressedImage__TYPE_HASH (Iron and Jazzy).
    assert_eq!(
        MessageKind::CompressedImage.type_hash(),
        "RIHS01_15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a"
    );
    assert_eq!(
        MessageKind::CompressedImage.dds_type_name(),
        "sensor_msgs::msg::dds_::CompressedImage_"
    );
}
