//! Getting Gaussians out of the world map: as a renderer `GaussianSet` in a local frame
//! (for PLY export and rendering, where f32 needs coordinates near the origin) and as a
//! bird's-eye-view picture.

use std::path::{Path, PathBuf};

use glam::{DAffine3, DQuat, DVec2};
use image::RgbImage;
use renderer::picture::unit_to_u8;
use renderer::{Gaussian, GaussianSet};

use super::{pose_problem, WorldGaussian};

/// Largest footprint radius of one Gaussian in a bird's-eye view, pixels.
const MAX_RADIUS_PX: f64 = 16.0;
/// Largest bird's-eye-view side, pixels (so a bad argument cannot exhaust memory).
const MAX_SIDE_PX: u32 = 16_384;

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The local frame is not a finite rigid transform.
    #[error("export frame {reason}")]
    BadFrame {
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A bird's-eye-view argument is out of range.
    #[error("bird's-eye view: {what}")]
    BadView {
        /// What is wrong.
        what: &'static str,
    },
    /// The PNG could not be written.
    #[error("writing {path}: {source}")]
    Png {
        /// The file.
        path: PathBuf,
        /// The encoder's or file system's error.
        source: image::ImageError,
    },
}

/// The Gaussians as a renderer set in the frame whose pose (frame to world) is
/// `frame_to_world`: positions relative to it in f64, then cast to f32; rotations
/// composed with the frame's inverse rotation. Pass `DAffine3::from_translation(origin)`
/// for a world-aligned frame around `origin`.
pub fn local_set<'a>(
    gaussians: impl IntoIterator<Item = &'a WorldGaussian>,
    frame_to_world: DAffine3,
) -> Result<GaussianSet, ExportError> {
    if let Some(reason) = pose_problem(&frame_to_world) {
        return Err(ExportError::BadFrame { reason });
    }
    let world_to_frame = frame_to_world.inverse();
    let inverse_rotation = DQuat::from_mat3(&frame_to_world.matrix3).conjugate();
    let mut set = GaussianSet::default();
    for g in gaussians {
        set.push(Gaussian {
            mean: world_to_frame.transform_point3(g.position).as_vec3(),
            log_scale: g.log_scale,
            rotation: (inverse_rotation * g.rotation.as_dquat())
                .normalize()
                .as_quat(),
            opacity: g.opacity,
            color: g.color,
            confidence: g.confidence,
        });
    }
    Ok(set)
}

/// A top-down orthographic view of the world's x-y plane (z up, as KITTI-360's world):
/// image columns grow with x, rows grow with -y (north up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BevView {
    /// World (x, y) at the image centre, metres.
    pub centre: DVec2,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Ground size of one pixel, metres.
    pub metres_per_pixel: f64,
    /// Colour of pixels no Gaussian covers.
    pub background: [u8; 3],
}

impl BevView {
    /// A square view of `side` pixels at `metres_per_pixel` around `centre`, black where no
    /// Gaussian lies (the published `map/bev` and the exported files).
    pub fn square(centre: DVec2, side: u32, metres_per_pixel: f64) -> Self {
        Self {
            centre,
            width: side,
            height: side,
            metres_per_pixel,
            background: [0, 0, 0],
        }
    }

    /// The view of the exported `global_map_bev.png`: 512 px at 0.25 m around `centre`
    /// (`eval-map` draws its bird's-eye views the same way, so they compare).
    pub fn export(centre: DVec2) -> Self {
        Self::square(centre, 512, 0.25)
    }

    /// The ground box (world x-y, min and max) holding the centre of every Gaussian that
    /// can touch the view: the view's extent plus the largest footprint radius and a pixel.
    pub fn ground_box(&self) -> (DVec2, DVec2) {
        let mpp = self.metres_per_pixel;
        let half = DVec2::new(self.width as f64, self.height as f64) * mpp / 2.0
            + (MAX_RADIUS_PX + 1.0) * mpp;
        (self.centre - half, self.centre + half)
    }

    fn validate(&self) -> Result<(), ExportError> {
        let what = if self.width == 0 || self.height == 0 {
            "width and height must be positive"
        } else if self.width > MAX_SIDE_PX || self.height > MAX_SIDE_PX {
            "width and height must be at most 16384"
        } else if !(self.metres_per_pixel.is_finite() && self.metres_per_pixel > 0.0) {
            "metres_per_pixel must be finite and positive"
        } else if !self.centre.is_finite() {
            "centre must be finite"
        } else {
            return Ok(());
        };
        Err(ExportError::BadView { what })
    }
}

/// Draws the Gaussians from above. Each Gaussian covers the pixel its centre falls in plus
/// every pixel whose centre lies within its largest standard deviation (at most 16 pixels)
/// of its centre; a pixel shows the colour (clamped to [0, 1]) of the highest (largest z)
/// Gaussian covering it, the first in iteration order on a tie.
pub fn bev_image<'a>(
    gaussians: impl IntoIterator<Item = &'a WorldGaussian>,
    view: &BevView,
) -> Result<RgbImage, ExportError> {
    view.validate()?;
    let (w, h) = (view.width as usize, view.height as usize);
    let mpp = view.metres_per_pixel;
    let x0 = view.centre.x - w as f64 * mpp / 2.0;
    let y_top = view.centre.y + h as f64 * mpp / 2.0;
    let mut top = vec![f64::NEG_INFINITY; w * h];
    let mut img = RgbImage::from_pixel(view.width, view.height, image::Rgb(view.background));
    for g in gaussians {
        if !g.position.is_finite() {
            continue;
        }
        // Continuous pixel coordinates: pixel (c, r) spans [c, c + 1) x [r, r + 1).
        let u = (g.position.x - x0) / mpp;
        let v = (y_top - g.position.y) / mpp;
        let radius = (f64::from(g.log_scale.max_element()).exp() / mpp).min(MAX_RADIUS_PX);
        let (home_c, home_r) = (u.floor(), v.floor());
        let c_lo = (u - radius).floor().max(0.0);
        let c_hi = (u + radius).floor().min(w as f64 - 1.0);
        let r_lo = (v - radius).floor().max(0.0);
        let r_hi = (v + radius).floor().min(h as f64 - 1.0);
        if c_lo > c_hi || r_lo > r_hi {
            continue;
        }
        let color = image::Rgb(g.color.to_array().map(unit_to_u8));
        for r in r_lo as usize..=r_hi as usize {
            for c in c_lo as usize..=c_hi as usize {
                let (du, dv) = (c as f64 + 0.5 - u, r as f64 + 0.5 - v);
                let home = c as f64 == home_c && r as f64 == home_r;
                let idx = r * w + c;
                if (home || du * du + dv * dv <= radius * radius) && g.position.z > top[idx] {
                    top[idx] = g.position.z;
                    img.put_pixel(c as u32, r as u32, color);
                }
            }
        }
    }
    Ok(img)
}

/// Writes a bird's-eye view (or any RGB image) as PNG, atomically ([`renderer::atomic`]).
pub fn save_bev_png(img: &RgbImage, path: impl AsRef<Path>) -> Result<(), ExportError> {
    let path = path.as_ref();
    renderer::atomic::write_atomic(path, |w| img.write_to(w, image::ImageFormat::Png)).map_err(
        |source| ExportError::Png {
            path: path.to_path_buf(),
            source,
        },
    )
}
