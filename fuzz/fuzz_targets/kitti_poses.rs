//! KITTI-360 pose files as `read_pose_file` reads them, each input as both `poses.txt`
//! (index + 3x4) and `cam0_to_world.txt` (index + 4x4).
#![no_main]

use model::kitti360::poses::{read_pose_file, PoseFormat};
use stereosplat_fuzz::scratch_file;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = scratch_file("poses.txt", data);
    for format in [PoseFormat::ThreeByFour, PoseFormat::FourByFour] {
        let _ = read_pose_file(&path, format);
    }
});
