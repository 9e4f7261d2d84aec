//! Reading a pair's image files: PNG or JPEG of any size and channel layout; grey (and grey
//! with alpha, RGBA, 16-bit) becomes 8-bit RGB with values / 255, as the rest of the project
//! holds images. A raw pair is rectified on the way in.

use std::path::Path;

use image::DynamicImage;
use model::frame::{Rgb8Image, RgbImage};

use super::PairError;
use crate::rectify::StereoRectifier;

/// Decodes any image file the `image` crate reads (format guessed from the bytes).
pub fn decode(path: &Path) -> Result<DynamicImage, PairError> {
    let bytes = std::fs::read(path).map_err(|source| PairError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    image::load_from_memory(&bytes).map_err(|source| PairError::Decode {
        path: path.to_path_buf(),
        source,
    })
}

/// The left and right images, which must have one size, rectified by `rectifier` when the
/// calibration describes raw cameras (8-bit RGB through each camera's remap table).
pub fn load_pair(
    left: &Path,
    right: &Path,
    rectifier: Option<&StereoRectifier>,
) -> Result<(RgbImage, RgbImage), PairError> {
    let (l, r) = (load_rgb8(left)?, load_rgb8(right)?);
    same_size(
        "left and right images",
        (l.width, l.height),
        (r.width, r.height),
    )?;
    let float = |i: &Rgb8Image| RgbImage::from_rgb8(i.width, i.height, &i.data);
    let Some(rectifier) = rectifier else {
        return Ok((float(&l), float(&r)));
    };
    let (w, h) = (rectifier.rig().left.width(), rectifier.rig().left.height());
    same_size("calibration and images", (w, h), (l.width, l.height))?;
    let (l, r) = rectifier
        .rectify(&l, &r)
        .map_err(|e| PairError::InconsistentCalibration(format!("rectifying the images: {e}")))?;
    Ok((float(&l), float(&r)))
}

/// The image at `path` as 8-bit RGB.
fn load_rgb8(path: &Path) -> Result<Rgb8Image, PairError> {
    let rgb = decode(path)?.to_rgb8();
    Ok(Rgb8Image {
        width: rgb.width(),
        height: rgb.height(),
        data: rgb.into_raw(),
    })
}

/// `a` and `b` are one size, else [`PairError::SizeMismatch`] naming `what`.
pub fn same_size(what: &str, a: (u32, u32), b: (u32, u32)) -> Result<(), PairError> {
    match a == b {
        true => Ok(()),
        false => Err(PairError::SizeMismatch {
            what: what.to_string(),
            a_w: a.0,
            a_h: a.1,
            b_w: b.0,
            b_h: b.1,
        }),
    }
}
