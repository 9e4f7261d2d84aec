//! The 3D-volume (triplane) branch of StereoSplat (paper section 3.2.2): plane queries in
//! the bin frame attend to the input views' features (with a sinusoidal pose code) and to
//! each other, the cost-volume Gaussians are fused into them, and a voxel decoder turns the
//! most occupied voxels inside the input frusta into Gaussians.

mod anchors;
mod branch;
mod cida;
mod config;
mod cpda;
mod decoder;
mod deformable;
mod encoder;
mod fusion;
mod head;
mod occupancy;
mod occupancy_target;
mod pose_encoding;
mod queries;
pub mod voxels;

pub use anchors::ViewAnchors;
pub use branch::{BranchInputs, VolumeBranch};
pub use cida::CrossImageAttention;
pub use config::{Plane, VolumeConfig, VolumeLayer};
pub use cpda::CrossPlaneAttention;
pub use decoder::{
    log_sigmoid, product_logit, VoxelDecoder, GAUSSIAN_PARAMS, MAX_OFFSET, MAX_SCALE,
};
pub use encoder::TriplaneEncoder;
pub use fusion::{gaussian_rows, ProjectionFusion};
pub use head::{GaussiansPerBranch, VolumeHead, VolumeOutput};
pub use occupancy::{frustum_mask, top_k, OccupancyHead, MIN_DEPTH};
pub use occupancy_target::{bin_lidar_points, occupancy_loss, occupied_voxels, BinPoints};
pub use pose_encoding::{so3_exp, so3_log, PoseEncoding};
pub use queries::{PlaneQueries, Planes};
