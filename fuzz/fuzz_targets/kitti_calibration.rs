//! The three KITTI-360 calibration files (`perspective.txt`, `calib_cam_to_pose.txt`,
//! `calib_cam_to_velo.txt`, joined by NULs in one input) as `Calibration::read` reads them,
//! then the stereo rig they make.
//! The body is `node::untrusted_input::kitti_calibration`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::kitti_calibration(data));
