//! The three KITTI-360 calibration files (`perspective.txt`, `calib_cam_to_pose.txt`,
//! `calib_cam_to_velo.txt`, joined by NULs in one input) as `Calibration::read` reads them,
//! then the stereo rig they make.
#![no_main]

use model::kitti360::{layout, Calibration};
use stereosplat_fuzz::{scratch_dir, split, write_file};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let root = scratch_dir();
    let [perspective, cam_to_pose, cam_to_velo] = split::<3>(data);
    for (path, bytes) in [
        (layout::perspective(root), perspective),
        (layout::cam_to_pose(root), cam_to_pose),
        (layout::cam_to_velo(root), cam_to_velo),
    ] {
        write_file(&path, bytes);
    }
    if let Ok(calibration) = Calibration::read(root) {
        let _ = calibration.rig();
    }
});
