//! The seeds of the camera image entries: `sensor_msgs/Image` in every encoding the node
//! reads (with padded rows, big-endian 16-bit values and an odd-sized Bayer image), and
//! `sensor_msgs/CompressedImage` as JPEG (colour and grey) and PNG (8-bit colour, 16-bit
//! grey with alpha).

use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder};
use model::frame::Rgb8Image;
use node::msg::compressed::{compressed_image, Compression};
use node::msg::encodings::Encoding;
use node::msg::image::image_with_encoding;
use node::msg::sensor_msgs::{CompressedImage, Image};
use node::msg::std_msgs::Header;
use node::msg::Message;

use super::{Seeds, STAMP};

/// Writes the seeds of `cdr_image` and `cdr_compressed_image`, made from `frame`.
pub fn write(seeds: &Seeds, frame: &Rgb8Image) -> anyhow::Result<()> {
    let header = || Header::new(STAMP, "cam_left");
    for encoding in Encoding::ALL {
        let msg = image_with_encoding(frame, encoding.name(), header())?;
        seeds.put("cdr_image", encoding.name(), &msg.encode())?;
    }
    let padded = padded(image_with_encoding(frame, "bgr8", header())?, 4);
    seeds.put("cdr_image", "bgr8_padded", &padded.encode())?;
    let mut big_endian = image_with_encoding(frame, "rgb16", header())?;
    big_endian.is_bigendian = 1;
    big_endian
        .data
        .chunks_exact_mut(2)
        .for_each(|p| p.swap(0, 1));
    seeds.put("cdr_image", "rgb16_big_endian", &big_endian.encode())?;
    let odd = Rgb8Image {
        width: frame.width - 1,
        height: frame.height - 1,
        data: frame
            .data
            .chunks_exact(3 * frame.width as usize)
            .take(frame.height as usize - 1)
            .flat_map(|row| &row[..3 * (frame.width as usize - 1)])
            .copied()
            .collect(),
    };
    let odd = image_with_encoding(&odd, "bayer_grbg8", header())?;
    seeds.put("cdr_image", "bayer_grbg8_odd", &odd.encode())?;

    for (name, compression) in [
        ("jpeg", Compression::Jpeg { quality: 90 }),
        ("png", Compression::Png),
    ] {
        let msg = compressed_image(frame, compression, header())?;
        seeds.put("cdr_compressed_image", name, &msg.encode())?;
    }
    let (w, h) = (frame.width, frame.height);
    let grey: Vec<u8> = frame.data.chunks_exact(3).map(|p| p[1]).collect();
    let mut data = Vec::new();
    JpegEncoder::new_with_quality(&mut data, 80).write_image(&grey, w, h, ExtendedColorType::L8)?;
    let grey_jpeg = compressed("mono8; jpeg compressed mono8", data);
    seeds.put("cdr_compressed_image", "jpeg_grey", &grey_jpeg.encode())?;
    let grey_alpha: Vec<u8> = grey
        .iter()
        .flat_map(|&v| [(v as u16 * 257).to_ne_bytes(), [7, 7]].concat())
        .collect();
    let mut data = Vec::new();
    PngEncoder::new(&mut data).write_image(&grey_alpha, w, h, ExtendedColorType::La16)?;
    let png16 = compressed("png", data);
    seeds.put("cdr_compressed_image", "png_grey_alpha_16", &png16.encode())?;
    Ok(())
}

/// `msg` with `extra` bytes of padding after every row.
fn padded(msg: Image, extra: u32) -> Image {
    let data = msg
        .data
        .chunks_exact(msg.step as usize)
        .flat_map(|row| [row, &vec![0xee; extra as usize]].concat())
        .collect();
    Image {
        step: msg.step + extra,
        data,
        ..msg
    }
}

/// A compressed image message of `data` in `format`.
fn compressed(format: &str, data: Vec<u8>) -> CompressedImage {
    CompressedImage {
        header: Header::new(STAMP, "cam_left"),
        format: format.into(),
        data,
    }
}
