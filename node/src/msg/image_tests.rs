//! Every encoding of `sensor_msgs/Image` written and read back from generated frames:
//! exact where the encoding keeps the RGB, the demosaiced PSNR of Bayer; padded rows,
//! big-endian 16-bit values, wrong sizes, and 0, 1 and 2 pixel wide and odd-sized images.

use super::*;
use crate::msg::demosaic::BayerPattern;
use crate::msg::test_frames::{psnr8, smooth, textured};

const BAYER: [BayerPattern; 4] = [
    BayerPattern::Rggb,
    BayerPattern::Bggr,
    BayerPattern::Gbrg,
    BayerPattern::Grbg,
];

fn encode(img: &Rgb8Image, encoding: Encoding) -> Image {
    image_with_encoding(img, encoding.name(), Header::new(5, "cam")).unwrap()
}

fn decode(msg: &Image) -> Rgb8Image {
    rgb8_from_image(msg.clone()).unwrap()
}

/// `img` with every pixel replaced by its grey (R = G = B = the BT.601 luma).
fn grey_of(img: &Rgb8Image) -> Rgb8Image {
    let mono = encode(img, Encoding::Mono8);
    Rgb8Image {
        data: mono.data.iter().flat_map(|&v| [v; 3]).collect(),
        ..img.clone()
    }
}

#[test]
fn colour_and_16_bit_encodings_round_trip_exactly() {
    let img = textured(37, 23);
    for encoding in [
        Encoding::Rgb8,
        Encoding::Bgr8,
        Encoding::Rgba8,
        Encoding::Bgra8,
        Encoding::Rgb16,
    ] {
        let msg = encode(&img, encoding);
        assert_eq!(msg.encoding, encoding.name());
        assert_eq!(msg.step, 37 * encoding.bytes_per_pixel());
        assert_eq!(decode(&msg), img, "{encoding:?}");
        let float = rgb_from_image(&msg).unwrap();
        assert_eq!(float, img.to_rgb(), "{encoding:?} as floats");
    }
    // The channel order on the wire: a pure red pixel.
    let red = Rgb8Image {
        width: 1,
        height: 1,
        data: vec![200, 10, 0],
    };
    assert_eq!(encode(&red, Encoding::Bgr8).data, [0, 10, 200]);
    assert_eq!(encode(&red, Encoding::Bgra8).data, [0, 10, 200, 255]);
    assert_eq!(encode(&red, Encoding::Rgba8).data, [200, 10, 0, 255]);
    // 200 * 257 = 0xc8c8, 10 * 257 = 0x0a0a, little endian.
    assert_eq!(
        encode(&red, Encoding::Rgb16).data,
        [0xc8, 0xc8, 0x0a, 0x0a, 0, 0]
    );
}

#[test]
fn grey_encodings_keep_the_luma_and_round_trip_grey_frames() {
    let img = textured(31, 17);
    let grey = grey_of(&img);
    for encoding in [Encoding::Mono8, Encoding::Mono16] {
        // A colour frame becomes its luma; a grey frame comes back as it was.
        assert_eq!(decode(&encode(&img, encoding)), grey, "{encoding:?}");
        assert_eq!(decode(&encode(&grey, encoding)), grey, "{encoding:?}");
    }
    // BT.601: (299 * 255 + 587 * 0 + 114 * 0) / 1000 = 76.2 -> 76.
    let red = Rgb8Image {
        width: 1,
        height: 1,
        data: vec![255, 0, 0],
    };
    assert_eq!(encode(&red, Encoding::Mono8).data, [76]);
}

#[test]
fn sixteen_bit_values_keep_their_high_byte_in_either_byte_order() {
    // 0x80ff: its high byte 0x80, not rounded up to 0x81.
    let mut msg = Image {
        header: Header::default(),
        height: 1,
        width: 2,
        encoding: "mono16".into(),
        is_bigendian: 0,
        step: 4,
        data: vec![0xff, 0x80, 0x34, 0x12],
    };
    assert_eq!(decode(&msg).data, [0x80, 0x80, 0x80, 0x12, 0x12, 0x12]);
    msg.is_bigendian = 1;
    assert_eq!(decode(&msg).data, [0xff, 0xff, 0xff, 0x34, 0x34, 0x34]);

    // Whole frames written little endian, swapped to big endian: the same pixels.
    let img = textured(19, 11);
    for encoding in [Encoding::Mono16, Encoding::Rgb16] {
        let le = encode(&img, encoding);
        let mut be = le.clone();
        be.is_bigendian = 1;
        be.data.chunks_exact_mut(2).for_each(|p| p.swap(0, 1));
        assert_eq!(decode(&be), decode(&le), "{encoding:?}");
        // The low byte is ignored.
        let mut wrong = le.clone();
        wrong.data.chunks_exact_mut(2).for_each(|p| p[0] ^= 0x0f);
        assert_eq!(
            decode(&wrong),
            decode(&le),
            "{encoding:?}: low byte ignored"
        );
    }
}

#[test]
fn bayer_demosaics_within_a_psnr_floor_and_constant_colours_exactly() {
    // Measured over the four patterns: smooth 55.0-56.5 dB; textured 27.6-27.7 dB, its
    // two-pixel stripes (at the filter array's sampling limit) and hard edges costing the
    // most, as bilinear demosaicing does.
    for pattern in BAYER {
        let encoding = Encoding::Bayer(pattern);
        for (name, img, floor) in [
            ("smooth", smooth(96, 64), 50.0),
            ("textured", textured(96, 64), 26.0),
        ] {
            let msg = encode(&img, encoding);
            assert_eq!((msg.step, msg.data.len()), (96, 96 * 64));
            let db = psnr8(&img, &decode(&msg));
            eprintln!("{} {name}: {db:.1} dB", encoding.name());
            assert!(db >= floor, "{} {name}: {db:.1} dB", encoding.name());
        }
    }
    // A constant colour comes back exactly at every size from 2x2, odd ones included.
    for pattern in BAYER {
        for (w, h) in [(2, 2), (3, 2), (2, 3), (5, 3), (7, 9), (4, 4)] {
            let img = Rgb8Image {
                width: w,
                height: h,
                data: [200, 100, 30].repeat((w * h) as usize),
            };
            let msg = encode(&img, Encoding::Bayer(pattern));
            assert_eq!(decode(&msg), img, "{pattern:?} {w}x{h}");
        }
    }
}

#[test]
fn bayer_patterns_put_each_channel_where_its_filter_is() {
    // RGGB 2x2: red top left, blue bottom right; every pixel gets the three of them.
    let msg = Image {
        header: Header::default(),
        height: 2,
        width: 2,
        encoding: "bayer_rggb8".into(),
        is_bigendian: 0,
        step: 2,
        data: vec![200, 100, 100, 50],
    };
    assert_eq!(decode(&msg).data, [200, 100, 50].repeat(4));
    let mut grbg = msg.clone();
    grbg.encoding = "bayer_grbg8".into();
    grbg.data = vec![100, 200, 50, 100];
    assert_eq!(decode(&grbg).data, [200, 100, 50].repeat(4));
    // Odd sizes of a textured frame decode, within the floor.
    for (w, h) in [(33, 21), (47, 15)] {
        let img = smooth(w, h);
        let back = decode(&encode(&img, Encoding::Bayer(BayerPattern::Bggr)));
        let db = psnr8(&img, &back);
        assert!(db >= 35.0, "{w}x{h}: {db:.1} dB");
    }
}

#[test]
fn bayer_images_one_pixel_wide_or_tall_are_refused() {
    for (w, h) in [(1, 1), (1, 7), (6, 1)] {
        let img = smooth(w, h);
        let msg = encode(&img, Encoding::Bayer(BayerPattern::Rggb));
        assert_eq!(
            rgb8_from_image(msg.clone()),
            Err(ConvertError::BayerTooSmall {
                width: w,
                height: h
            })
        );
        assert!(rgb_from_image(&msg).is_err());
    }
}

#[test]
fn rows_padded_in_step_read_as_packed_ones() {
    let img = textured(13, 7);
    for encoding in Encoding::ALL {
        let packed = encode(&img, encoding);
        let row = packed.step as usize;
        let mut padded = packed.clone();
        padded.step += 5;
        padded.data = packed
            .data
            .chunks_exact(row)
            .flat_map(|r| [r, &[0xab; 5]].concat())
            .collect();
        assert_eq!(decode(&padded), decode(&packed), "{encoding:?}");
    }
}

#[test]
fn packed_rgb8_is_taken_without_a_copy() {
    let msg = encode(&textured(8, 4), Encoding::Rgb8);
    let at = msg.data.as_ptr();
    assert_eq!(rgb8_from_image(msg).unwrap().data.as_ptr(), at);
}

#[test]
fn a_wrong_step_or_data_length_is_an_error() {
    let img = textured(6, 4);
    for encoding in Encoding::ALL {
        let good = encode(&img, encoding);
        let min_step = good.step as u64;
        let mut short_step = good.clone();
        short_step.step -= 1;
        short_step.data.truncate((short_step.step * 4) as usize);
        let mut short_data = good.clone();
        short_data.data.pop();
        let mut long_data = good.clone();
        long_data.data.push(0);
        let mut huge = good.clone();
        huge.height = u32::MAX;
        for bad in [short_step, short_data, long_data, huge] {
            let err = rgb8_from_image(bad.clone()).unwrap_err();
            assert_eq!(
                err,
                ConvertError::ImageSize {
                    width: bad.width,
                    height: bad.height,
                    encoding: encoding.name().to_owned(),
                    step: bad.step,
                    min_step,
                    len: bad.data.len(),
                },
                "{encoding:?}"
            );
            assert!(rgb_from_image(&bad).is_err());
        }
    }
}

#[test]
fn images_without_pixels_are_empty_in_every_encoding() {
    for encoding in Encoding::ALL {
        for (w, h) in [(0, 0), (0, 5), (5, 0)] {
            let img = Rgb8Image {
                width: w,
                height: h,
                data: Vec::new(),
            };
            let msg = encode(&img, encoding);
            assert!(msg.data.is_empty());
            assert_eq!(decode(&msg), img, "{encoding:?} {w}x{h}");
        }
    }
}

#[test]
fn other_encodings_are_refused_by_name_and_the_message_lists_what_is_read() {
    for name in ["yuv422", "16UC1", "RGB8", "", "bayer_rggb16"] {
        let msg = Image {
            encoding: name.into(),
            ..Image::default()
        };
        let err = rgb8_from_image(msg).unwrap_err();
        assert_eq!(err, ConvertError::UnsupportedEncoding(name.to_owned()));
        let text = err.to_string();
        for encoding in Encoding::ALL {
            assert!(text.contains(encoding.name()), "{text}");
        }
        assert_eq!(
            image_with_encoding(&smooth(2, 2), name, Header::default()),
            Err(ConvertError::UnsupportedEncoding(name.to_owned()))
        );
    }
    for encoding in Encoding::ALL {
        assert_eq!(Encoding::parse(encoding.name()), Some(encoding));
    }
}

#[test]
fn frames_too_large_for_a_message_are_refused_when_written() {
    // A row of more than 4 GiB in rgb16 (never allocated: the size is checked first).
    let wide = Rgb8Image {
        width: u32::MAX / 4,
        height: 1,
        data: Vec::new(),
    };
    assert_eq!(
        image_with_encoding(&wide, "rgb16", Header::default()),
        Err(ConvertError::TooLarge("image row"))
    );
    let tall = Rgb8Image {
        width: 1 << 16,
        height: 1 << 16,
        data: Vec::new(),
    };
    assert_eq!(
        image_with_encoding(&tall, "mono8", Header::default()),
        Err(ConvertError::TooLarge("image"))
    );
}
