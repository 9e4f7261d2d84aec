//! The 3D-volume (triplane) branch of StereoSplat (paper section 3.2.2): plane queries in
//! the bin frame attend to the input views' features (with a sinusoidal pose code) and to
//! each other, the cost-volume Gaussians are fused into them, and a voxel decoder turns the
//! most occupied voxels inside the input frusta into Gaussians.

mod anchors;
mod cida;
mod config;
mod cpda;
mod deformable;
mod encoder;
mod pose_encoding;
mod queries;

pub use anchors::ViewAnchors;
pub use cida::CrossImageAttention;
pub use config::{Plane, VolumeConfig, VolumeLayer};
pub use cpda::CrossPlaneAttention;
pub use encoder::TriplaneEncoder;
pub use pose_encoding::{so3_exp, so3_log, PoseEncoding};
pub use queries::{PlaneQueries, Planes};
