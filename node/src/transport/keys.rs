//! The zenoh keys of the node's topics. Every topic lives under one namespace so several
//! nodes can share a zenoh network. Two key modes:
//!
//! - **plain** (default): `<namespace>/<topic>`, e.g. `stereosplat/left/image`;
//! - **ros2**: the keys rmw_zenoh uses, so ROS 2 nodes on rmw_zenoh see the topics:
//!   `<domain_id>/<namespace>/<topic>/<pkg>::msg::dds_::<Name>_/<RIHS01 type hash>`, e.g.
//!   `0/stereosplat/left/image/sensor_msgs::msg::dds_::Image_/RIHS01_d31d…`. In this mode
//!   every sample carries rmw_zenoh's attachment ([`crate::transport::ros2`]).
//!
//! `/tf` and `/tf_static` are absolute (a name starting with `/`): ROS tools read them there
//! whatever the node's namespace, so their keys are `tf` and `tf_static` (ros2:
//! `<domain_id>/tf/...`). Each topic has the QoS profile ROS 2 publishers of it use
//! (tf2's for the transforms, rclcpp's default for the rest), announced in rmw_zenoh's
//! liveliness tokens and recorded in MCAP channel metadata.

use crate::msg::MessageKind;
use crate::transport::ros2::{Durability, History, Qos, Reliability};

/// Which way a topic flows, seen from the node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// The node subscribes.
    Input,
    /// The node publishes.
    Output,
}

/// One of the node's topics: its name under the namespace, its message type and QoS.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Topic {
    /// The name under the namespace, e.g. `left/image`, or an absolute name, e.g. `/tf`.
    pub name: &'static str,
    /// The message it carries.
    pub kind: MessageKind,
    /// Subscribed or published by the node.
    pub direction: Direction,
    /// The QoS profile of its publishers and subscriptions.
    pub qos: Qos,
}

const fn topic(name: &'static str, kind: MessageKind, direction: Direction) -> Topic {
    Topic {
        name,
        kind,
        direction,
        qos: Qos::NODE,
    }
}

/// sensor_msgs/Image, the left image, rectified or raw (input).
pub const LEFT_IMAGE: Topic = topic("left/image", MessageKind::Image, Direction::Input);
/// sensor_msgs/Image, the right image, rectified or raw (input).
pub const RIGHT_IMAGE: Topic = topic("right/image", MessageKind::Image, Direction::Input);
/// sensor_msgs/CompressedImage, the left image as JPEG or PNG (input; image_transport's
/// `compressed` transport of [`LEFT_IMAGE`]).
pub const LEFT_COMPRESSED: Topic = topic(
    "left/image/compressed",
    MessageKind::CompressedImage,
    Direction::Input,
);
/// sensor_msgs/CompressedImage, the right image as JPEG or PNG (input).
pub const RIGHT_COMPRESSED: Topic = topic(
    "right/image/compressed",
    MessageKind::CompressedImage,
    Direction::Input,
);
/// sensor_msgs/CameraInfo of the left camera (input).
pub const LEFT_INFO: Topic = topic(
    "left/camera_info",
    MessageKind::CameraInfo,
    Direction::Input,
);
/// sensor_msgs/CameraInfo of the right camera, `P[3] = -fx * baseline` (input).
pub const RIGHT_INFO: Topic = topic(
    "right/camera_info",
    MessageKind::CameraInfo,
    Direction::Input,
);
/// geometry_msgs/PoseStamped, left camera to world (input).
pub const POSE: Topic = topic("pose", MessageKind::PoseStamped, Direction::Input);
/// nav_msgs/Odometry of the robot's body, the pose source of `--pose-source odometry`
/// (input).
pub const ODOMETRY: Topic = topic("odometry", MessageKind::Odometry, Direction::Input);
/// sensor_msgs/PointCloud2, each bin's Gaussian map in the bin frame (output).
pub const BIN_MAP: Topic = topic("bin/map", MessageKind::PointCloud2, Direction::Output);
/// geometry_msgs/PoseStamped, each bin frame's pose in the world, f64 (output).
pub const BIN_POSE: Topic = topic("bin/pose", MessageKind::PoseStamped, Direction::Output);
/// sensor_msgs/Image, the bin map rendered from its input (left) view (output, optional).
pub const BIN_RENDER: Topic = topic("bin/render", MessageKind::Image, Direction::Output);
/// sensor_msgs/Image, a bird's-eye view of the global map around the latest bin (output,
/// optional).
pub const MAP_BEV: Topic = topic("map/bev", MessageKind::Image, Direction::Output);
/// stereosplat_msgs/MapUpdate, the global map's increments and snapshots (output).
pub const MAP_UPDATE: Topic = topic("map/update", MessageKind::MapUpdate, Direction::Output);
/// stereosplat_msgs/BinLatency, per bin (output).
pub const LATENCY: Topic = topic("latency", MessageKind::BinLatency, Direction::Output);
/// stereosplat_msgs/Diagnostics, the node's counters (output).
pub const DIAGNOSTICS: Topic = topic("diagnostics", MessageKind::Diagnostics, Direction::Output);
/// tf2_msgs/TFMessage on `/tf`: world -> the left camera at every frame (output). QoS as
/// tf2's `TransformBroadcaster`: reliable, volatile, keep last 100.
pub const TF: Topic = Topic {
    name: "/tf",
    kind: MessageKind::TfMessage,
    direction: Direction::Output,
    qos: Qos {
        reliability: Reliability::Reliable,
        durability: Durability::Volatile,
        history: History::KeepLast(100),
    },
};
/// tf2_msgs/TFMessage on `/tf_static`: world -> `bin_<id>` for every bin so far, the whole
/// set in each message (output). QoS as tf2's `StaticTransformBroadcaster`: reliable,
/// transient local, keep last 1.
pub const TF_STATIC: Topic = Topic {
    name: "/tf_static",
    kind: MessageKind::TfMessage,
    direction: Direction::Output,
    qos: Qos {
        reliability: Reliability::Reliable,
        durability: Durability::TransientLocal,
        history: History::KeepLast(1),
    },
};

/// Every topic of the node, inputs first.
pub const TOPICS: [Topic; 17] = [
    LEFT_IMAGE,
    RIGHT_IMAGE,
    LEFT_INFO,
    RIGHT_INFO,
    POSE,
    LEFT_COMPRESSED,
    RIGHT_COMPRESSED,
    ODOMETRY,
    BIN_MAP,
    BIN_POSE,
    BIN_RENDER,
    MAP_BEV,
    MAP_UPDATE,
    LATENCY,
    DIAGNOSTICS,
    TF,
    TF_STATIC,
];

/// How topic names become zenoh keys.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum KeyMode {
    /// `<namespace>/<topic>`.
    #[default]
    Plain,
    /// rmw_zenoh's `<domain_id>/<namespace>/<topic>/<dds type>/<type hash>`.
    Ros2 {
        /// The ROS domain id (`ROS_DOMAIN_ID`, 0 by default).
        domain_id: u32,
    },
}

/// The node's topics under a namespace, in a key mode.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Keys {
    /// The namespace, without leading or trailing slashes (default `stereosplat`).
    pub namespace: String,
    /// Plain or ROS 2 keys.
    pub mode: KeyMode,
}

impl Keys {
    /// Plain keys under `namespace`.
    pub fn new(namespace: impl Into<String>) -> Self {
        Self::with_mode(namespace, KeyMode::Plain)
    }

    /// Keys under `namespace` in `mode`.
    pub fn with_mode(namespace: impl Into<String>, mode: KeyMode) -> Self {
        Self {
            namespace: namespace.into().trim_matches('/').to_string(),
            mode,
        }
    }

    /// The zenoh key of `topic`.
    pub fn key(&self, topic: Topic) -> String {
        let name = self.topic_name(topic);
        match self.mode {
            KeyMode::Plain => name,
            KeyMode::Ros2 { domain_id } => format!(
                "{domain_id}/{name}/{}/{}",
                topic.kind.dds_type_name(),
                topic.kind.type_hash()
            ),
        }
    }

    /// The topic's name without a leading slash, `<namespace>/<topic>`, or an absolute
    /// topic's name without its slash (what ROS 2 calls the topic is this with a leading
    /// slash).
    pub fn topic_name(&self, topic: Topic) -> String {
        if let Some(absolute) = topic.name.strip_prefix('/') {
            absolute.to_string()
        } else if self.namespace.is_empty() {
            topic.name.to_string()
        } else {
            format!("{}/{}", self.namespace, topic.name)
        }
    }

    /// Every topic with its key, inputs first.
    pub fn all(&self) -> Vec<(String, Topic)> {
        TOPICS.iter().map(|&t| (self.key(t), t)).collect()
    }

    /// The topic a received key belongs to, if it is one of the node's.
    pub fn topic_of(&self, key: &str) -> Option<Topic> {
        TOPICS.iter().copied().find(|&t| self.key(t) == key)
    }

    /// sensor_msgs/Image, the left image, rectified or raw (input).
    pub fn left_image(&self) -> String {
        self.key(LEFT_IMAGE)
    }

    /// sensor_msgs/Image, the right image, rectified or raw (input).
    pub fn right_image(&self) -> String {
        self.key(RIGHT_IMAGE)
    }

    /// nav_msgs/Odometry of the robot's body (input, `--pose-source odometry`).
    pub fn odometry(&self) -> String {
        self.key(ODOMETRY)
    }

    /// sensor_msgs/CompressedImage, the left image as JPEG or PNG (input).
    pub fn left_compressed(&self) -> String {
        self.key(LEFT_COMPRESSED)
    }

    /// sensor_msgs/CompressedImage, the right image as JPEG or PNG (input).
    pub fn right_compressed(&self) -> String {
        self.key(RIGHT_COMPRESSED)
    }

    /// sensor_msgs/CameraInfo of the left camera (input).
    pub fn left_info(&self) -> String {
        self.key(LEFT_INFO)
    }

    /// sensor_msgs/CameraInfo of the right camera (input).
    pub fn right_info(&self) -> String {
        self.key(RIGHT_INFO)
    }

    /// geometry_msgs/PoseStamped, left camera to world (input).
    pub fn pose(&self) -> String {
        self.key(POSE)
    }

    /// sensor_msgs/PointCloud2, each bin's Gaussian map (output).
    pub fn bin_map(&self) -> String {
        self.key(BIN_MAP)
    }

    /// geometry_msgs/PoseStamped, each bin frame's world pose (output).
    pub fn bin_pose(&self) -> String {
        self.key(BIN_POSE)
    }

    /// sensor_msgs/Image, the bin map rendered from its input view (output).
    pub fn bin_render(&self) -> String {
        self.key(BIN_RENDER)
    }

    /// sensor_msgs/Image, bird's-eye view of the global map (output).
    pub fn map_bev(&self) -> String {
        self.key(MAP_BEV)
    }

    /// stereosplat_msgs/MapUpdate, global map increments and snapshots (output).
    pub fn map_update(&self) -> String {
        self.key(MAP_UPDATE)
    }

    /// A key expression matching every input key (and the outputs too: subscribers filter
    /// with [`Keys::topic_of`]).
    pub fn input_wildcard(&self) -> String {
        let ns = match self.namespace.is_empty() {
            true => String::new(),
            false => format!("{}/", self.namespace),
        };
        match self.mode {
            KeyMode::Plain => format!("{ns}**"),
            KeyMode::Ros2 { domain_id } => format!("{domain_id}/{ns}**"),
        }
    }

    /// The zenoh queryable answering with a stereosplat_msgs/MapUpdate snapshot of the global
    /// map: `<namespace>/map/snapshot` in both modes (a zenoh query, not a ROS 2 service).
    pub fn snapshot_request(&self) -> String {
        if self.namespace.is_empty() {
            "map/snapshot".into()
        } else {
            format!("{}/map/snapshot", self.namespace)
        }
    }

    /// A worker process's key, `<ns>/workers/<id>`: its queryable (bins in, maps out) and
    /// its liveliness token (the node sees it come and go).
    pub fn worker(&self, id: &str) -> String {
        format!("{}/{id}", self.workers())
    }

    /// The prefix of every worker process's key, `<ns>/workers`.
    pub fn workers(&self) -> String {
        if self.namespace.is_empty() {
            "workers".into()
        } else {
            format!("{}/workers", self.namespace)
        }
    }

    /// stereosplat_msgs/BinLatency, per bin (output).
    pub fn latency(&self) -> String {
        self.key(LATENCY)
    }

    /// stereosplat_msgs/Diagnostics, the node's counters (output).
    pub fn diagnostics(&self) -> String {
        self.key(DIAGNOSTICS)
    }
}

impl Default for Keys {
    fn default() -> Self {
        Self::new("stereosplat")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plain_keys_are_namespace_slash_topic() {
        let keys = Keys::new("/robot/ss/");
        assert_eq!(keys.left_image(), "robot/ss/left/image");
        assert_eq!(keys.topic_of("robot/ss/latency"), Some(LATENCY));
        assert_eq!(keys.topic_of("robot/ss/nothing"), None);
        assert_eq!(keys.key(TF_STATIC), "tf_static");
        assert_eq!(keys.topic_of("tf"), Some(TF));
    }

    #[test]
    fn ros2_keys_follow_rmw_zenoh() {
        let keys = Keys::with_mode("stereosplat", KeyMode::Ros2 { domain_id: 7 });
        assert_eq!(
            keys.left_image(),
            format!(
                "7/stereosplat/left/image/sensor_msgs::msg::dds_::Image_/{}",
                MessageKind::Image.type_hash()
            )
        );
        assert_eq!(
            keys.key(TF),
            "7/tf/tf2_msgs::msg::dds_::TFMessage_/RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"
        );
        let all = keys.all();
        assert_eq!(all.len(), TOPICS.len());
        for (key, topic) in all {
            assert_eq!(keys.topic_of(&key), Some(topic));
        }
    }
}
