//! The one-step enhancer of StereoSplat+ (paper section 3.3), in the role of the paper's
//! diffusion model (Difix3D+'s SD-Turbo, fine-tuned), but trained here from scratch: no
//! SD-Turbo weights can be had, and with no noise and one fixed step Difix is an
//! image-to-image network. It keeps Difix's structure at a size the 2-core CPU runs:
//!
//! - input: the render of a novel view with its alpha and confidence (5 channels) and the
//!   reference view (the bin's first left input image);
//! - a 3-level U-Net ([`encoder`], [`decoder`]; 32/48/64 channels at 1/4..1/16 in `tiny`)
//!   shared by both views, the reference mixed in by [`joint_attention`] at 1/16 (one
//!   self-attention over both views' tokens, no weights of its own);
//! - output: the render plus a predicted residual at full resolution, clamped to `[0, 1]`,
//!   the identity at initialisation ([`network`]);
//! - training pairs made by the project's own StereoSplat ([`make_pairs`], on disk as
//!   [`pairs`]), loss L2 + LPIPS + a Gram (style) term on the LPIPS network's features
//!   ([`loss`]), training as StereoSplat's ([`train`]), scores of raw against enhanced
//!   renders ([`evaluate`]).

pub mod config;
pub mod decoder;
pub mod encoder;
pub mod evaluate;
pub mod joint_attention;
pub mod loss;
pub mod make_pairs;
pub mod network;
pub mod pairs;
pub mod train;

use std::path::{Path, PathBuf};

pub use config::{Config, UnknownPreset, PRESETS};
pub use network::Enhancer;

/// The shipped weights of a preset, `enhancer_<preset>.safetensors`, found as
/// [`crate::assets`] says.
pub fn default_weights(preset: &str) -> PathBuf {
    crate::assets::weights_file(&format!("enhancer_{preset}.safetensors"))
}

/// The enhancer of `cfg` with weights from `path` (safetensors, f32), on `device`.
pub fn load(
    cfg: &Config,
    path: &Path,
    device: &candle_core::Device,
) -> Result<Enhancer, EnhanceError> {
    let tensors = crate::assets::load_tensors(path, device)?;
    let vb = candle_nn::VarBuilder::from_tensors(tensors, candle_core::DType::F32, device);
    Ok(Enhancer::new(vb, cfg)?)
}

/// Why making pairs, training or evaluating the enhancer failed.
#[derive(Debug, thiserror::Error)]
pub enum EnhanceError {
    /// The drives could not be read.
    #[error(transparent)]
    Data(#[from] crate::train::DataError),
    /// A frame could not be read.
    #[error(transparent)]
    Kitti360(#[from] crate::kitti360::Kitti360Error),
    /// StereoSplat's weights could not be loaded.
    #[error(transparent)]
    Weights(#[from] crate::net::LoadError),
    /// StereoSplat failed on a bin.
    #[error(transparent)]
    Reconstruct(#[from] crate::reconstruct::ReconstructError),
    /// A render failed.
    #[error("rendering failed: {0}")]
    Render(#[from] renderer::gpu::GpuError),
    /// A tensor operation failed.
    #[error(transparent)]
    Tensor(#[from] candle_core::Error),
    /// Training's checkpoint, log or curve failed.
    #[error(transparent)]
    Train(#[from] crate::train::TrainError),
    /// The weights to start from lack some of the enhancer's weights (another preset).
    #[error("{path} lacks the enhancer weights {missing}: is it of another preset?")]
    InitIncomplete {
        /// The weights file.
        path: PathBuf,
        /// The weights it lacks, comma-separated.
        missing: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A picture could not be read or written.
    #[error("{path}: {source}")]
    Image {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: image::ImageError,
    },
    /// A picture's buffer does not fit its size (a bug).
    #[error("{0}: picture buffer does not match its size")]
    Size(PathBuf),
    /// A row of `pairs.csv` is malformed.
    #[error("{path}: malformed row `{line}`")]
    Index {
        /// The index file.
        path: PathBuf,
        /// The row.
        line: String,
    },
    /// The pair folder holds no pair.
    #[error("no training pairs in {0} (make them with `stereosplat research enhancer-data`)")]
    NoPairs(PathBuf),
}

impl EnhanceError {
    /// An I/O error about `path`.
    pub fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Self {
        let path = path.to_path_buf();
        move |source| Self::Io { path, source }
    }

    fn size(path: &Path) -> Self {
        Self::Size(path.to_path_buf())
    }
}
