//! The rectified images, `data_2d_raw/<seq>/image_0x/data_rect/%010d.png`: 8-bit RGB PNGs
//! (grey, grey+alpha, RGBA and 16-bit PNGs are accepted and converted to 8-bit RGB).

use std::path::Path;

use image::{codecs::png::PngEncoder, ExtendedColorType, ImageEncoder, ImageFormat};

use super::error::Kitti360Error;
use super::text::create_parent;
use crate::frame::{Rgb8Image, RgbImage};

/// Decodes one PNG into [0, 1] RGB; a missing file is [`Kitti360Error::MissingFile`], one
/// that does not decode is [`Kitti360Error::Png`].
pub fn read_png(path: &Path) -> Result<RgbImage, Kitti360Error> {
    Ok(read_png_rgb8(path)?.to_rgb())
}

/// Decodes one PNG into interleaved 8-bit RGB (what a replay publishes as it is). Errors as
/// [`read_png`].
pub fn read_png_rgb8(path: &Path) -> Result<Rgb8Image, Kitti360Error> {
    let bytes = std::fs::read(path).map_err(|e| Kitti360Error::io(path, e))?;
    let decoded = image::load_from_memory_with_format(&bytes, ImageFormat::Png).map_err(|e| {
        Kitti360Error::Png {
            path: path.into(),
            reason: e.to_string(),
        }
    })?;
    let rgb = decoded.to_rgb8();
    Ok(Rgb8Image {
        width: rgb.width(),
        height: rgb.height(),
        data: rgb.into_raw(),
    })
}

/// Encodes an image as an 8-bit RGB PNG (values clamped and rounded, no gamma), creating
/// the directory. An image whose data length does not match its size is refused.
pub fn write_png(path: &Path, image: &RgbImage) -> Result<(), Kitti360Error> {
    let expected = 3 * image.width as usize * image.height as usize;
    if image.data.len() != expected || expected == 0 {
        return Err(Kitti360Error::Png {
            path: path.into(),
            reason: format!(
                "{}x{} image holds {} values, {expected} expected (and at least one pixel)",
                image.width,
                image.height,
                image.data.len()
            ),
        });
    }
    let mut bytes = Vec::new();
    PngEncoder::new(&mut bytes)
        .write_image(
            &image.to_rgb8(),
            image.width,
            image.height,
            ExtendedColorType::Rgb8,
        )
        .map_err(|e| Kitti360Error::Png {
            path: path.into(),
            reason: e.to_string(),
        })?;
    create_parent(path)?;
    std::fs::write(path, bytes).map_err(|e| Kitti360Error::io(path, e))
}
