//! Camera images and calibration: [`RgbImage`] <-> `sensor_msgs/Image`, and
//! `sensor_msgs/CameraInfo` <-> rectified [`Intrinsics`] plus stereo baseline.

use model::frame::{Rgb8Image, RgbImage};
use renderer::Intrinsics;

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

/// The image of an `rgb8`, `bgr8` or `mono8` message (grey copied to the three channels),
/// values as bytes / 255. Any other encoding, a step shorter than a row, or data other than
/// `step * height` bytes is an error.
pub fn rgb_from_image(msg: &Image) -> Result<RgbImage, ConvertError> {
    let channels = channels(msg)?;
    Ok(RgbImage::from_rgb8(
        msg.width,
        msg.height,
        &packed(msg, channels),
    ))
}

/// [`rgb_from_image`] as packed bytes; an `rgb8` message without row padding gives its
/// data as it is, without a copy. Same errors.
pub fn rgb8_from_image(msg: Image) -> Result<Rgb8Image, ConvertError> {
    let channels = channels(&msg)?;
    let data = match msg.encoding == "rgb8" && msg.step as u64 == 3 * msg.width as u64 {
        true => msg.data,
        false => packed(&msg, channels),
    };
    Ok(Rgb8Image {
        width: msg.width,
        height: msg.height,
        data,
    })
}

/// The bytes per pixel of a valid message's encoding, after checking its step and size.
fn channels(msg: &Image) -> Result<usize, ConvertError> {
    let channels: usize = match msg.encoding.as_str() {
        "rgb8" | "bgr8" => 3,
        "mono8" => 1,
        other => return Err(ConvertError::UnsupportedEncoding(other.to_owned())),
    };
    let min_step = msg.width as u64 * channels as u64;
    if (msg.step as u64) < min_step || msg.data.len() as u64 != msg.step as u64 * msg.height as u64
    {
        return Err(ConvertError::ImageSize {
            width: msg.width,
            height: msg.height,
            encoding: msg.encoding.clone(),
            step: msg.step,
            min_step,
            len: msg.data.len(),
        });
    }
    Ok(channels)
}

/// A checked message's pixels as packed RGB bytes.
fn packed(msg: &Image, channels: usize) -> Vec<u8> {
    // Bounded by the data checked: width * height <= data.len().
    let row_bytes = msg.width as usize * channels;
    let mut rgb = Vec::with_capacity(3 * msg.width as usize * msg.height as usize);
    let rows = msg.data.chunks_exact(msg.step.max(1) as usize);
    for row in rows.take(msg.height as usize) {
        for px in row[..row_bytes].chunks_exact(channels) {
            match (msg.encoding.as_str(), px) {
                ("bgr8", &[b, g, r]) => rgb.extend([r, g, b]),
                (_, &[v]) => rgb.extend([v, v, v]),
                _ => rgb.extend_from_slice(px),
            }
        }
    }
    rgb
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
