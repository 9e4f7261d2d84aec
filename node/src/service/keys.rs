//! The zenoh keys of the node's topics (plain mode: `<namespace>/<topic>`). Every key lives
//! under one namespace so several nodes can share a zenoh network.

/// The node's topics under a namespace.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Keys {
    /// The namespace, without a trailing slash (default `stereosplat`).
    pub namespace: String,
}

impl Keys {
    /// Topics under `namespace`.
    pub fn new(namespace: impl Into<String>) -> Self {
        Self {
            namespace: namespace.into().trim_end_matches('/').to_string(),
        }
    }

    fn key(&self, topic: &str) -> String {
        format!("{}/{topic}", self.namespace)
    }

    /// sensor_msgs/Image, the rectified left image (input).
    pub fn left_image(&self) -> String {
        self.key("left/image")
    }

    /// sensor_msgs/Image, the rectified right image (input).
    pub fn right_image(&self) -> String {
        self.key("right/image")
    }

    /// sensor_msgs/CameraInfo of the left camera (input).
    pub fn left_info(&self) -> String {
        self.key("left/camera_info")
    }

    /// sensor_msgs/CameraInfo of the right camera, P[3] = -fx * baseline (input).
    pub fn right_info(&self) -> String {
        self.key("right/camera_info")
    }

    /// geometry_msgs/PoseStamped, left camera to world (input).
    pub fn pose(&self) -> String {
        self.key("pose")
    }

    /// sensor_msgs/PointCloud2, each bin's Gaussian map in the bin frame (output).
    pub fn bin_map(&self) -> String {
        self.key("bin/map")
    }

    /// geometry_msgs/PoseStamped, each bin frame's pose in the world, f64 (output).
    pub fn bin_pose(&self) -> String {
        self.key("bin/pose")
    }

    /// stereosplat_msgs/BinLatency, per bin (output).
    pub fn latency(&self) -> String {
        self.key("latency")
    }

    /// stereosplat_msgs/Diagnostics, the node's counters (output).
    pub fn diagnostics(&self) -> String {
        self.key("diagnostics")
    }
}

impl Default for Keys {
    fn default() -> Self {
        Self::new("stereosplat")
    }
}
