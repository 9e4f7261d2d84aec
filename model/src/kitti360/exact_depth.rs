//! Exact per-pixel depth of generated drives, `data_2d_exact_depth/<seq>/image_0x/%010d.png`:
//! a project extension of the layout (real KITTI-360 has no such folder). 16-bit grey PNGs,
//! value = z-depth x [`DEPTH_SCALE`] rounded (KITTI's depth-map convention: 1/256 m steps up
//! to 256 m), 0 where the pixel centre sees the sky or lies beyond the range. The evaluation
//! uses them to find the target pixels the input pair did not see (unseen-region PSNR).

use std::path::Path;

use image::{codecs::png::PngEncoder, ExtendedColorType, ImageEncoder, ImageFormat};

use super::error::Kitti360Error;
use super::text::create_parent;
use crate::frame::DepthMap;

/// Stored value per metre of depth.
pub const DEPTH_SCALE: f32 = 256.0;

fn png_error(path: &Path, reason: impl ToString) -> Kitti360Error {
    Kitti360Error::Png {
        path: path.into(),
        reason: reason.to_string(),
    }
}

/// Writes `depth` (metres, 0 = none) as a 16-bit PNG, creating the directory. Depths that
/// are not finite, not positive or beyond the format's range are written as 0 (none).
pub fn write_depth_png(path: &Path, depth: &DepthMap) -> Result<(), Kitti360Error> {
    let expected = depth.width as usize * depth.height as usize;
    if depth.data.len() != expected || expected == 0 {
        return Err(png_error(
            path,
            format!(
                "{}x{} depth map holds {} values, {expected} expected (and at least one pixel)",
                depth.width,
                depth.height,
                depth.data.len()
            ),
        ));
    }
    let bytes: Vec<u8> = depth
        .data
        .iter()
        .map(|&d| {
            let v = (d * DEPTH_SCALE).round();
            if d.is_finite() && v >= 1.0 && v <= u16::MAX as f32 {
                v as u16
            } else {
                0
            }
        })
        .flat_map(u16::to_ne_bytes)
        .collect();
    let mut png = Vec::new();
    PngEncoder::new(&mut png)
        .write_image(&bytes, depth.width, depth.height, ExtendedColorType::L16)
        .map_err(|e| png_error(path, e))?;
    create_parent(path)?;
    std::fs::write(path, png).map_err(|e| Kitti360Error::io(path, e))
}

/// Reads a depth PNG written by [`write_depth_png`] (any PNG decodes; it is read as 16-bit
/// grey). A missing file is [`Kitti360Error::MissingFile`].
pub fn read_depth_png(path: &Path) -> Result<DepthMap, Kitti360Error> {
    let bytes = std::fs::read(path).map_err(|e| Kitti360Error::io(path, e))?;
    let decoded = image::load_from_memory_with_format(&bytes, ImageFormat::Png)
        .map_err(|e| png_error(path, e))?
        .into_luma16();
    Ok(DepthMap {
        width: decoded.width(),
        height: decoded.height(),
        data: decoded
            .as_raw()
            .iter()
            .map(|&v| v as f32 / DEPTH_SCALE)
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_round_trips_in_256ths_of_a_metre_and_clips_what_it_cannot_hold() {
        let dir = std::env::temp_dir().join(format!("stereosplat-depth-{}", std::process::id()));
        let path = dir.join("a/b.png");
        let depth = DepthMap {
            width: 3,
            height: 2,
            data: vec![0.0, 1.0, 12.3456, 255.99, 300.0, f32::NAN],
        };
        write_depth_png(&path, &depth).unwrap();
        let back = read_depth_png(&path).unwrap();
        assert_eq!((back.width, back.height), (3, 2));
        let want = [
            0.0,
            1.0,
            (12.3456f32 * 256.0).round() / 256.0,
            255.98828,
            0.0,
            0.0,
        ];
        for (got, want) in back.data.iter().zip(want) {
            assert!((got - want).abs() < 1e-4, "{:?}", back.data);
        }
        let bad = DepthMap {
            width: 2,
            height: 2,
            data: vec![1.0],
        };
        assert!(matches!(
            write_depth_png(&path, &bad),
            Err(Kitti360Error::Png { .. })
        ));
        assert!(matches!(
            read_depth_png(&dir.join("none.png")),
            Err(Kitti360Error::MissingFile { .. })
        ));
        std::fs::write(&path, b"not a png").unwrap();
        assert!(matches!(
            read_depth_png(&path),
            Err(Kitti360Error::Png { .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
