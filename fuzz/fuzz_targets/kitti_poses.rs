//! KITTI-360 pose files as `read_pose_file` reads them, each input as both `poses.txt`
//! (index + 3x4) and `cam0_to_world.txt` (index + 4x4).
//! The body is `node::untrusted_input::kitti_poses`, which the test suite's seeded mutations
//! call too.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| node::untrusted_input::kitti_poses(data));
