//! `run`'s flags for where the left camera's poses come from: the `pose` topic, `/tf`, or
//! the odometry topic (docs/robot-topics.md, "Poses").

use anyhow::Result;
use clap::{Args, ValueEnum};

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
    /// mount on `/tf_static`.
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
                mount: Mount::TfStatic,
            },
        };
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
