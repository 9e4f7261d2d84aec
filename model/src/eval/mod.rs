//! The evaluation protocol of the paper's section 4: for every bin of a sequence, a
//! reconstructor sees only the bin's first stereo pair; every frame of the bin is rendered
//! from the reconstruction (left and right) and scored against the recorded images (PSNR,
//! SSIM, optionally LPIPS) and the LiDAR depth (AbsRel, SqRel); on generated drives also on
//! the pixels the input pair never saw ([`unseen`]). [`report`] turns the scores into the
//! paper's table, [`pictures`] draws a few bins.

pub mod pictures;
pub mod report;
pub mod run;
pub mod unseen;

pub use renderer::Raster;
pub use report::{BinReport, EvalReport, FrameScore, MeanScores, SkippedBin, Summary};
pub use run::{evaluate, score_frame, EvalConfig, EvalError, FrameTarget};
