//! Where a command's Gaussians and camera come from: a map file (PLY, SPZ or glTF binary, told
//! apart by content) or a seeded generated scene,
//! seen by a camera at the origin looking down +z unless told otherwise.

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use renderer::{scene, Camera, GaussianSet, Intrinsics};

/// Generated scenes, for runs without a map file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum GeneratedScene {
    /// Two stereo views' worth of pixel-aligned Gaussians on a street-like layout, one per
    /// pixel of the image size (the paper's input at 544x112 is 121,856 Gaussians).
    PixelAligned,
    /// `--gaussians` Gaussians scattered through the view, 0.5 to 4 px across.
    Random,
}

/// Flags that choose the scene and the camera.
#[derive(Args, Clone, Debug)]
pub struct SceneArgs {
    /// A map to load instead of generating a scene: 3DGS PLY, SPZ or glTF binary with
    /// KHR_gaussian_splatting, told apart by content (`--ply` is the same flag).
    #[arg(long, visible_alias = "ply")]
    pub map: Option<std::path::PathBuf>,
    /// Which scene to generate when no `--map` is given.
    #[arg(long, value_enum, default_value = "pixel-aligned")]
    pub scene: GeneratedScene,
    /// Number of Gaussians for `--scene random`.
    #[arg(long, default_value_t = 100_000)]
    pub gaussians: usize,
    /// Seed of the generated scene.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Image width, pixels.
    #[arg(long, default_value_t = 544)]
    pub width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 112)]
    pub height: u32,
    /// Horizontal field of view of the camera, degrees (square pixels, centred principal point).
    #[arg(long, default_value_t = 90.0)]
    pub hfov: f32,
}

impl SceneArgs {
    /// The camera: at the origin, looking down +z.
    pub fn camera(&self) -> Result<Camera> {
        if self.width == 0 || self.height == 0 {
            bail!(
                "image size must be positive, got {}x{}",
                self.width,
                self.height
            );
        }
        if !(self.hfov > 0.0 && self.hfov < 180.0) {
            bail!(
                "--hfov must be between 0 and 180 degrees, got {}",
                self.hfov
            );
        }
        Ok(Camera::identity(Intrinsics::from_hfov(
            self.width,
            self.height,
            self.hfov,
        )))
    }

    /// The Gaussians: loaded from `--map` (any of the three formats), or generated.
    pub fn gaussians(&self, cam: &Camera) -> Result<GaussianSet> {
        if let Some(path) = &self.map {
            return renderer::formats::load_map(path)
                .map(|(_, set)| set)
                .with_context(|| format!("reading {}", path.display()));
        }
        Ok(match self.scene {
            GeneratedScene::PixelAligned => {
                scene::pixel_aligned(self.seed, &cam.intrinsics, 2, 0.6)
            }
            GeneratedScene::Random => {
                scene::random_in_view(self.seed, self.gaussians, &cam.intrinsics)
            }
        })
    }
}
