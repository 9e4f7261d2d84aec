//! Pictures of a bin: for its first, centre and last frames (left camera), one PNG with the
//! recorded image, the render, the rendered depth colour-mapped and the per-pixel error,
//! stacked top to bottom, so a reader sees at a glance where a method fails.

use std::path::Path;

use renderer::picture::{depth_to_rgb8, viridis, DepthScale};
use renderer::RenderOutput;

use super::report::{BinReport, FrameScore};
use crate::frame::{RgbImage, Side};
use crate::metrics::error_map;

/// Mean absolute RGB error drawn at the top of the error colour map.
pub const ERROR_MAP_MAX: f32 = 0.25;

/// A rendered frame of a bin beside what it is scored against, kept for pictures.
pub struct ScoredRender {
    /// The score.
    pub score: FrameScore,
    /// The recorded image.
    pub truth: RgbImage,
    /// The render.
    pub render: RenderOutput,
}

/// Writes `<dir>/<sequence>_bin<first>_<role>.png` for the bin's named frames (left camera).
pub fn write_bin(
    dir: &Path,
    sequence: &str,
    report: &BinReport,
    renders: &[ScoredRender],
) -> Result<(), Box<dyn std::error::Error>> {
    std::fs::create_dir_all(dir)?;
    for r in renders {
        let (Some(role), Side::Left) = (r.score.role, r.score.side) else {
            continue;
        };
        let (w, h) = (r.truth.width, r.truth.height);
        let render = RgbImage {
            width: w,
            height: h,
            data: r.render.rgb.clone(),
        };
        let errors = error_map(&render, &r.truth)?;
        let mut sheet = r.truth.to_rgb8();
        sheet.extend(render.to_rgb8());
        sheet.extend(depth_to_rgb8(&r.render, DepthScale::Auto)?);
        sheet.extend(errors.iter().flat_map(|e| viridis(e / ERROR_MAP_MAX)));
        let role = serde_json::to_value(role)?;
        let name = format!(
            "{sequence}_bin{:010}_{}.png",
            report.first,
            role.as_str().unwrap_or("frame")
        );
        image::save_buffer(
            dir.join(name),
            &sheet,
            w,
            4 * h,
            image::ExtendedColorType::Rgb8,
        )?;
    }
    Ok(())
}
