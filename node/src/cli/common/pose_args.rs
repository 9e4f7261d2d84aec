//! `run`'s flags for where the left camera's poses come from: the `pose` topic, `/tf`, or
//! the odometry topic (docs/robot-topics.md, "Poses").

use anyhow::Result;
use clap::{Args, ValueEnum};
use glam::{DAffine3, DQuat, DVec3};

use crate::tf::{Mount, PoseSourceConfig, PoseSourceKind};

/// Where poses come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PoseSourceArg {
    /// geometry_msgs/PoseStamped of the left camera on the `pose` topic.
    Pose,
    /// The `/tf` + `/tf_static` tree, looked up from `--world-frame` to the left camera's
    /// frame at each image's stamp.
    Tf,
    /// nav_msgs/Odometry of the robot's body on the `odometry` topic, with the camera's
    /// mount on `/tf_static` (or `--camera-mount`).
    Odometry,
}

/// Flags of the pose source.
#[derive(Args, Clone, Debug)]
#[command(next_help_heading = "Poses")]
pub struct PoseArgs {
    /// Where the left camera's poses come from.
    #[arg(long, value_enum, default_value_t = PoseSourceArg::Pose)]
    pose_source: PoseSourceArg,
    /// The frame the poses are in (`map`, `odom`, ...), and the frame of the node's outputs
    /// (maps, bin poses, transforms; `world` when not given). Needed with `--pose-source
    /// tf`; with `odometry`, the odometry's own `header.frame_id` when not given.
    #[arg(long)]
    world_frame: Option<String>,
    /// The left camera's optical frame; by default each left image's `header.frame_id`.
    #[arg(long)]
    camera_frame: Option<String>,
    /// The camera's mount on the odometry's body frame, for `--pose-source odometry`
    /// without it on `/tf_static`: `x,y,z,qx,qy,qz,qw`, the left camera's optical frame in
    /// the body frame (metres and a unit quaternion, as `static_transform_publisher` takes
    /// them).
    #[arg(long, value_parser = parse_mount, allow_hyphen_values = true)]
    camera_mount: Option<DAffine3>,
    /// Milliseconds an image waits for the transform at its stamp before it is given up
    /// (counted as `pose_source/timed_out`).
    #[arg(long, default_value_t = 500.0)]
    pose_wait_ms: f64,
}

impl PoseArgs {
    /// The frame of the node's outputs: `--world-frame`, or `world`.
    pub fn world_frame(&self) -> String {
        self.world_frame
            .clone()
            .unwrap_or_else(|| crate::msg::tf2_msgs::WORLD.into())
    }

    /// The node's pose source (`None`: the `pose` topic).
    pub fn config(&self) -> Result<Option<PoseSourceConfig>> {
        let kind = match self.pose_source {
            PoseSourceArg::Pose => return Ok(None),
            PoseSourceArg::Tf => {
                anyhow::ensure!(
                    self.world_frame.is_some(),
                    "--pose-source tf needs --world-frame (the frame poses are in, e.g. map)"
                );
                PoseSourceKind::Tf
            }
            PoseSourceArg::Odometry => PoseSourceKind::Odometry {
                mount: self.camera_mount.map_or(Mount::TfStatic, Mount::Fixed),
            },
        };
        anyhow::ensure!(
            self.camera_mount.is_none() || self.pose_source == PoseSourceArg::Odometry,
            "--camera-mount is the camera's mount on the odometry's body: it needs --pose-source odometry"
        );
        anyhow::ensure!(
            self.pose_wait_ms.is_finite() && self.pose_wait_ms >= 0.0,
            "--pose-wait-ms must be a number of milliseconds, 0 or more"
        );
        let mut config = PoseSourceConfig::new(kind, self.world_frame.clone());
        config.camera_frame = self.camera_frame.clone();
        config.wait_ns = (self.pose_wait_ms * 1e6) as i64;
        Ok(Some(config))
    }
}

/// `x,y,z,qx,qy,qz,qw` as a rigid transform: seven finite numbers, the quaternion of unit
/// length within 1e-3 (then normalised), as printed calibrations round it.
fn parse_mount(text: &str) -> Result<DAffine3, String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{text:?}: {e}"))?;
    let [x, y, z, qx, qy, qz, qw] = values[..] else {
        return Err(format!(
            "{text:?}: seven numbers x,y,z,qx,qy,qz,qw expected"
        ));
    };
    if !values.iter().all(|v| v.is_finite()) {
        return Err(format!("{text:?}: not every number is finite"));
    }
    let q = DQuat::from_xyzw(qx, qy, qz, qw);
    if (q.length() - 1.0).abs() > 1e-3 {
        return Err(format!(
            "{text:?}: the quaternion's length is {}, not 1",
            q.length()
        ));
    }
    Ok(DAffine3::from_rotation_translation(
        q.normalize(),
        DVec3::new(x, y, z),
    ))
}

#[cfg(test)]
mod tests {
    use super::parse_mount;

    #[test]
    fn a_mount_parses_and_bad_ones_are_named() {
        let m = parse_mount("1.2,0,1.5,-0.5,0.5,-0.5,0.5").unwrap();
        assert!((m.translation.x - 1.2).abs() < 1e-12);
        // REP 103's optical frame: its z (forward) is the body's x.
        let forward = m.transform_vector3(glam::DVec3::Z);
        assert!((forward - glam::DVec3::X).length() < 1e-12, "{forward}");
        for bad in [
            "1,2,3",
            "1,2,3,0,0,0,2",
            "1,2,nan,0,0,0,1",
            "1,2,3,0,0,0,1e400",
            "a",
        ] {
            assert!(parse_mount(bad).is_err(), "{bad}");
        }
        // Huge but finite values: a rigid transform, finite.
        assert!(parse_mount("1e300,0,0,0,0,0,1").unwrap().is_finite());
    }
}
