//! Camera images and calibration: [`RgbImage`] and [`Rgb8Image`] <-> `sensor_msgs/Image` in
//! every encoding of [`super::encodings`], and `sensor_msgs/CameraInfo` <-> rectified
//! [`Intrinsics`] plus stereo baseline.

use model::frame::{Rgb8Image, RgbImage};
use renderer::Intrinsics;

use super::encodings::{encode_rows, packed_rgb, Encoding};
use super::sensor_msgs::{CameraInfo, Image};
use super::std_msgs::Header;
use super::ConvertError;

/// An `rgb8` image message of `img` (values in [0, 1] clamped and rounded to bytes; rows
/// packed, `step = 3 * width`).
pub fn image_from_rgb(img: &RgbImage, header: Header) -> Image {
    image_from_rgb8(
        Rgb8Image {
            width: img.width,
            height: img.height,
            data: img.to_rgb8(),
        },
        header,
    )
}

/// An `rgb8` image message of `img`, rows packed.
pub fn image_from_rgb8(img: Rgb8Image, header: Header) -> Image {
    Image {
        header,
        height: img.height,
        width: img.width,
        encoding: "rgb8".to_owned(),
        is_bigendian: 0,
        step: img.width.saturating_mul(3),
        data: img.data,
    }
}

/// The message of `img` in `encoding` (a name [`Encoding::parse`] reads), rows packed and
/// 16-bit values little endian: grey is the BT.601 luma, 16-bit values are `byte * 257`,
/// Bayer keeps each pixel's filtered channel. What the project's players and tests publish
/// for every encoding the node reads; an encoding not read is
/// [`ConvertError::UnsupportedEncoding`], a row or image too large for the message's
/// 32-bit sizes [`ConvertError::TooLarge`], an `img` whose data is not `3 * width * height`
/// bytes [`ConvertError::ImageSize`].
pub fn image_with_encoding(
    img: &Rgb8Image,
    encoding: &str,
    header: Header,
) -> Result<Image, ConvertError> {
    let parsed = Encoding::parse(encoding)
        .ok_or_else(|| ConvertError::UnsupportedEncoding(encoding.to_owned()))?;
    let step = u32::try_from(img.width as u64 * parsed.bytes_per_pixel() as u64)
        .map_err(|_| ConvertError::TooLarge("image row"))?;
    if u32::try_from(step as u64 * img.height as u64).is_err() {
        return Err(ConvertError::TooLarge("image"));
    }
    let rgb_step = 3 * img.width as u64;
    if img.data.len() as u64 != rgb_step * img.height as u64 {
        return Err(ConvertError::ImageSize {
            width: img.width,
            height: img.height,
            encoding: "rgb8".to_owned(),
            step: img.width.saturating_mul(3),
            min_step: rgb_step,
            len: img.data.len(),
        });
    }
    Ok(Image {
        header,
        height: img.height,
        width: img.width,
        encoding: parsed.name().to_owned(),
        is_bigendian: 0,
        step,
        data: encode_rows(img, parsed),
    })
}

/// The image of a message in any encoding [`Encoding`] reads (see [`super::encodings`] for
/// how each becomes RGB), values as bytes / 255. Any other encoding, a step shorter than a
/// row, data other than `step * height` bytes, or a Bayer image 1 pixel wide or tall is an
/// error.
pub fn rgb_from_image(msg: &Image) -> Result<RgbImage, ConvertError> {
    let encoding = Encoding::of(msg)?;
    Ok(RgbImage::from_rgb8(
        msg.width,
        msg.height,
        &packed_rgb(msg, encoding),
    ))
}

/// [`rgb_from_image`] as packed bytes; an `rgb8` message without row padding gives its
/// data as it is, without a copy. Same errors.
pub fn rgb8_from_image(msg: Image) -> Result<Rgb8Image, ConvertError> {
    let encoding = Encoding::of(&msg)?;
    let data = match encoding == Encoding::Rgb8 && msg.step as u64 == 3 * msg.width as u64 {
        true => msg.data,
        false => packed_rgb(&msg, encoding),
    };
    Ok(Rgb8Image {
        width: msg.width,
        height: msg.height,
        data,
    })
}

/// The calibration message of one rectified camera of a stereo rig: no distortion
/// (`plumb_bob` with five zeros), identity `R`, `K` from the intrinsics and
/// `P = [fx 0 cx Tx; 0 fy cy 0; 0 0 1 0]` with `Tx = -fx * baseline`, as ROS writes the right
/// camera (`baseline = 0` for the left one).
pub fn camera_info(k: &Intrinsics, baseline: f64, header: Header) -> CameraInfo {
    let (fx, fy, cx, cy) = (k.fx as f64, k.fy as f64, k.cx as f64, k.cy as f64);
    CameraInfo {
        header,
        height: k.height,
        width: k.width,
        distortion_model: "plumb_bob".to_owned(),
        d: vec![0.0; 5],
        k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [
            fx,
            0.0,
            cx,
            -fx * baseline,
            0.0,
            fy,
            cy,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
        ],
        binning_x: 0,
        binning_y: 0,
        roi: Default::default(),
    }
}

/// The rectified intrinsics (from `P`) and the baseline (`-P[3] / fx`, 0 for a left camera)
/// of a calibration message; focal lengths must be positive and every used value finite.
pub fn intrinsics_from_camera_info(msg: &CameraInfo) -> Result<(Intrinsics, f64), ConvertError> {
    let p = &msg.p;
    let (fx, fy, cx, cy, tx) = (p[0], p[5], p[2], p[6], p[3]);
    for (v, name) in [
        (fx, "p[0]"),
        (fy, "p[5]"),
        (cx, "p[2]"),
        (cy, "p[6]"),
        (tx, "p[3]"),
    ] {
        if !v.is_finite() {
            return Err(ConvertError::NonFinite(name));
        }
    }
    if fx <= 0.0 || fy <= 0.0 {
        return Err(ConvertError::BadFocal { fx, fy });
    }
    let k = Intrinsics {
        fx: fx as f32,
        fy: fy as f32,
        cx: cx as f32,
        cy: cy as f32,
        width: msg.width,
        height: msg.height,
    };
    Ok((k, -tx / fx))
}

#[cfg(test)]
#[path = "image_tests.rs"]
mod tests;
