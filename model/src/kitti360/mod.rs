//! Reading and writing the KITTI-360 dataset layout for the perspective stereo pair, poses
//! and velodyne scans, so the model trains and is judged on real KITTI-360 when a user has
//! it, and on synthetic sequences written in the same layout when not.
//!
//! Under a root, for a sequence such as `2013_05_28_drive_0000_sync` ([`layout`] has the
//! exact paths):
//! - `calibration/`: `perspective.txt`, `calib_cam_to_pose.txt`, `calib_cam_to_velo.txt`
//!   ([`calibration`] explains each and how they combine);
//! - `data_2d_raw/<seq>/image_0{0,1}/data_rect/%010d.png` and `timestamps.txt`;
//! - `data_poses/<seq>/poses.txt` and `cam0_to_world.txt` ([`poses`]);
//! - `data_3d_raw/<seq>/velodyne_points/data/%010d.bin` and `timestamps.txt` ([`velodyne`]);
//! - generated drives only: `data_2d_exact_depth/<seq>/image_0{0,1}/%010d.png`
//!   ([`exact_depth`]).
//!
//! Only frames with a pose exist for this reader, as for KITTI-360's own tools.

pub mod calibration;
pub mod error;
pub mod exact_depth;
pub mod images;
pub mod laps;
pub mod layout;
pub mod lidar_depth;
pub mod poses;
pub mod resample;
pub mod sequence;
pub mod text;
pub mod timestamps;
pub mod velodyne;
pub mod writer;

pub use calibration::Calibration;
pub use error::Kitti360Error;
pub use poses::{FramePose, SkippedFrame};
pub use sequence::Sequence;
pub use writer::SequenceWriter;
