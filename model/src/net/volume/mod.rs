//! The 3D-volume (triplane) branch of StereoSplat (paper section 3.2.2): plane queries in
//! the bin frame attend to the input views' features (with a sinusoidal pose code) and to
//! each other, the cost-volume Gaussians are fused into them, and a voxel decoder turns the
//! most occupied voxels inside the input frusta into Gaussians.

mod config;

pub use config::{Plane, VolumeConfig, VolumeLayer};
