//! Where each file of a KITTI-360 sequence lives under the dataset root, as the official
//! download unpacks it (and as `kitti360scripts` looks for it).

use std::path::{Path, PathBuf};

use crate::frame::Side;

/// `calibration/perspective.txt`: rectified intrinsics `S_rect_0x`, `R_rect_0x`, `P_rect_0x`.
pub fn perspective(root: &Path) -> PathBuf {
    root.join("calibration").join("perspective.txt")
}

/// `calibration/calib_cam_to_pose.txt`: unrectified camera to GPS/IMU pose frame.
pub fn cam_to_pose(root: &Path) -> PathBuf {
    root.join("calibration").join("calib_cam_to_pose.txt")
}

/// `calibration/calib_cam_to_velo.txt`: unrectified camera 0 to velodyne.
pub fn cam_to_velo(root: &Path) -> PathBuf {
    root.join("calibration").join("calib_cam_to_velo.txt")
}

/// `data_2d_raw`: one directory per sequence.
pub fn images_root(root: &Path) -> PathBuf {
    root.join("data_2d_raw")
}

fn camera_dir(root: &Path, seq: &str, side: Side) -> PathBuf {
    let cam = match side {
        Side::Left => "image_00",
        Side::Right => "image_01",
    };
    images_root(root).join(seq).join(cam)
}

/// `data_2d_raw/<seq>/image_0x/data_rect/%010d.png`: a rectified image.
pub fn image(root: &Path, seq: &str, side: Side, index: u32) -> PathBuf {
    camera_dir(root, seq, side)
        .join("data_rect")
        .join(format!("{index:010}.png"))
}

/// `data_2d_exact_depth/<seq>/image_0x/%010d.png`: exact depth of a generated frame (a
/// project extension; see [`super::exact_depth`]).
pub fn exact_depth(root: &Path, seq: &str, side: Side, index: u32) -> PathBuf {
    let cam = camera_dir(root, seq, side);
    root.join("data_2d_exact_depth")
        .join(seq)
        .join(
            cam.file_name()
                .expect("camera_dir ends in the camera's folder"),
        )
        .join(format!("{index:010}.png"))
}

/// `data_2d_raw/<seq>/image_0x/timestamps.txt`: one capture time per frame, line k = frame k.
pub fn image_timestamps(root: &Path, seq: &str, side: Side) -> PathBuf {
    camera_dir(root, seq, side).join("timestamps.txt")
}

/// `data_poses/<seq>/poses.txt`: frame index and 3x4 GPS/IMU-to-world.
pub fn poses(root: &Path, seq: &str) -> PathBuf {
    root.join("data_poses").join(seq).join("poses.txt")
}

/// `data_poses/<seq>/cam0_to_world.txt`: frame index and 4x4 rectified-camera-0-to-world.
pub fn cam0_to_world(root: &Path, seq: &str) -> PathBuf {
    root.join("data_poses").join(seq).join("cam0_to_world.txt")
}

fn velodyne_dir(root: &Path, seq: &str) -> PathBuf {
    root.join("data_3d_raw").join(seq).join("velodyne_points")
}

/// `data_3d_raw/<seq>/velodyne_points/data/%010d.bin`: one scan, float32 x y z reflectance.
pub fn velodyne(root: &Path, seq: &str, index: u32) -> PathBuf {
    velodyne_dir(root, seq)
        .join("data")
        .join(format!("{index:010}.bin"))
}

/// `data_3d_raw/<seq>/velodyne_points/timestamps.txt`: one time per scan, line k = scan k.
pub fn velodyne_timestamps(root: &Path, seq: &str) -> PathBuf {
    velodyne_dir(root, seq).join("timestamps.txt")
}

/// True when `name` can be a sequence directory (one path component, not `.` or `..`).
pub fn valid_sequence_name(name: &str) -> bool {
    !name.is_empty() && name != "." && name != ".." && !name.contains(['/', '\\'])
}
