//! Which message a payload holds: ROS names, DDS names, `.msg` definitions and type hashes
//! of every type this module encodes.

use super::latency::{BIN_LATENCY_MSG, COUNTER_MSG, DIAGNOSTICS_MSG};
use super::map_update::MAP_UPDATE_MSG;
use super::type_hash::rihs01;
use std::sync::OnceLock;

/// Every message type this module encodes, nested ones included.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MessageKind {
    /// `builtin_interfaces/msg/Time`.
    Time,
    /// `std_msgs/msg/Header`.
    Header,
    /// `sensor_msgs/msg/Image`.
    Image,
    /// `sensor_msgs/msg/RegionOfInterest`.
    RegionOfInterest,
    /// `sensor_msgs/msg/CompressedImage`.
    CompressedImage,
    /// `sensor_msgs/msg/CameraInfo`.
    CameraInfo,
    /// `sensor_msgs/msg/PointField`.
    PointField,
    /// `sensor_msgs/msg/PointCloud2`.
    PointCloud2,
    /// `geometry_msgs/msg/Point`.
    Point,
    /// `geometry_msgs/msg/Quaternion`.
    Quaternion,
    /// `geometry_msgs/msg/Pose`.
    Pose,
    /// `geometry_msgs/msg/PoseStamped`.
    PoseStamped,
    /// `geometry_msgs/msg/Vector3`.
    Vector3,
    /// `geometry_msgs/msg/Transform`.
    Transform,
    /// `geometry_msgs/msg/TransformStamped`.
    TransformStamped,
    /// `geometry_msgs/msg/PoseWithCovariance`.
    PoseWithCovariance,
    /// `geometry_msgs/msg/Twist`.
    Twist,
    /// `geometry_msgs/msg/TwistWithCovariance`.
    TwistWithCovariance,
    /// `tf2_msgs/msg/TFMessage`.
    TfMessage,
    /// `nav_msgs/msg/Odometry`.
    Odometry,
    /// `nav_msgs/msg/Path`.
    Path,
    /// `stereosplat_msgs/msg/BinLatency`.
    BinLatency,
    /// `stereosplat_msgs/msg/Counter`.
    Counter,
    /// `stereosplat_msgs/msg/Diagnostics`.
    Diagnostics,
    /// `stereosplat_msgs/msg/MapUpdate`.
    MapUpdate,
}

impl MessageKind {
    /// All kinds, in declaration order.
    pub const ALL: [MessageKind; 25] = [
        Self::Time,
        Self::Header,
        Self::Image,
        Self::RegionOfInterest,
        Self::CompressedImage,
        Self::CameraInfo,
        Self::PointField,
        Self::PointCloud2,
        Self::Point,
        Self::Quaternion,
        Self::Pose,
        Self::PoseStamped,
        Self::Vector3,
        Self::Transform,
        Self::TransformStamped,
        Self::PoseWithCovariance,
        Self::Twist,
        Self::TwistWithCovariance,
        Self::TfMessage,
        Self::Odometry,
        Self::Path,
        Self::BinLatency,
        Self::Counter,
        Self::Diagnostics,
        Self::MapUpdate,
    ];

    /// The ROS 2 name, `package/msg/Type`.
    pub fn ros_name(self) -> &'static str {
        match self {
            Self::Time => "builtin_interfaces/msg/Time",
            Self::Header => "std_msgs/msg/Header",
            Self::Image => "sensor_msgs/msg/Image",
            Self::RegionOfInterest => "sensor_msgs/msg/RegionOfInterest",
            Self::CompressedImage => "sensor_msgs/msg/CompressedImage",
            Self::CameraInfo => "sensor_msgs/msg/CameraInfo",
            Self::PointField => "sensor_msgs/msg/PointField",
            Self::PointCloud2 => "sensor_msgs/msg/PointCloud2",
            Self::Point => "geometry_msgs/msg/Point",
            Self::Quaternion => "geometry_msgs/msg/Quaternion",
            Self::Pose => "geometry_msgs/msg/Pose",
            Self::PoseStamped => "geometry_msgs/msg/PoseStamped",
            Self::Vector3 => "geometry_msgs/msg/Vector3",
            Self::Transform => "geometry_msgs/msg/Transform",
            Self::TransformStamped => "geometry_msgs/msg/TransformStamped",
            Self::PoseWithCovariance => "geometry_msgs/msg/PoseWithCovariance",
            Self::Twist => "geometry_msgs/msg/Twist",
            Self::TwistWithCovariance => "geometry_msgs/msg/TwistWithCovariance",
            Self::TfMessage => "tf2_msgs/msg/TFMessage",
            Self::Odometry => "nav_msgs/msg/Odometry",
            Self::Path => "nav_msgs/msg/Path",
            Self::BinLatency => "stereosplat_msgs/msg/BinLatency",
            Self::Counter => "stereosplat_msgs/msg/Counter",
            Self::Diagnostics => "stereosplat_msgs/msg/Diagnostics",
            Self::MapUpdate => "stereosplat_msgs/msg/MapUpdate",
        }
    }

    /// The kind of a ROS 2 name (`package/msg/Type`), if this module encodes it.
    pub fn from_ros_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.ros_name() == name)
    }

    /// The DDS type name rmw_zenoh puts in key expressions and liveliness tokens:
    /// `package::msg::dds_::Type_`.
    pub fn dds_type_name(self) -> String {
        let (package, ty) = self.ros_name().split_once("/msg/").unwrap_or_default();
        format!("{package}::msg::dds_::{ty}_")
    }

    /// The `.msg` definition (fields only for the standard types, as in ROS 2 Jazzy's
    /// `common_interfaces` and `rcl_interfaces`; comments and constants left out, as they
    /// do not enter the type hash or the wire format).
    pub fn definition(self) -> &'static str {
        match self {
            Self::Time => "int32 sec\nuint32 nanosec\n",
            Self::Header => "builtin_interfaces/Time stamp\nstring frame_id\n",
            Self::Image => {
                "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n\
                 uint8 is_bigendian\nuint32 step\nuint8[] data\n"
            }
            Self::RegionOfInterest => {
                "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n"
            }
            Self::CompressedImage => "std_msgs/Header header\nstring format\nuint8[] data\n",
            Self::CameraInfo => {
                "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n\
                 float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n\
                 uint32 binning_y\nRegionOfInterest roi\n"
            }
            Self::PointField => "string name\nuint32 offset\nuint8 datatype\nuint32 count\n",
            Self::PointCloud2 => {
                "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\n\
                 bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\n\
                 bool is_dense\n"
            }
            Self::Point => "float64 x\nfloat64 y\nfloat64 z\n",
            Self::Quaternion => "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
            Self::Pose => "Point position\nQuaternion orientation\n",
            Self::PoseStamped => "std_msgs/Header header\nPose pose\n",
            Self::Vector3 => "float64 x\nfloat64 y\nfloat64 z\n",
            Self::Transform => "Vector3 translation\nQuaternion rotation\n",
            Self::TransformStamped => {
                "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"
            }
            Self::PoseWithCovariance => "Pose pose\nfloat64[36] covariance\n",
            Self::Twist => "Vector3 linear\nVector3 angular\n",
            Self::TwistWithCovariance => "Twist twist\nfloat64[36] covariance\n",
            Self::TfMessage => "geometry_msgs/TransformStamped[] transforms\n",
            Self::Odometry => {
                "std_msgs/Header header\nstring child_frame_id\n\
                 geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n"
            }
            Self::Path => "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses\n",
            Self::BinLatency => BIN_LATENCY_MSG,
            Self::Counter => COUNTER_MSG,
            Self::Diagnostics => DIAGNOSTICS_MSG,
            Self::MapUpdate => MAP_UPDATE_MSG,
        }
    }

    /// The REP 2011 type hash, `RIHS01_<64 hex>`, computed from the definitions above the
    /// way `rosidl_generator_type_description` does (see [`rihs01`]); computed once.
    pub fn type_hash(self) -> &'static str {
        static HASHES: OnceLock<Vec<String>> = OnceLock::new();
        let hashes = HASHES.get_or_init(|| {
            Self::ALL
                .iter()
                .map(|k| {
                    rihs01(k.ros_name(), |name| {
                        Self::from_ros_name(name).map(|k| k.definition())
                    })
                    // The definitions are constants of this file; a test hashes every one.
                    .expect("the built-in message definitions parse")
                })
                .collect()
        });
        // `ALL` lists the variants in declaration order (tested), so the discriminant indexes it.
        &hashes[self as usize]
    }
}

/// The REP 2011 type hash of `kind` (see [`MessageKind::type_hash`]).
pub fn type_hash(kind: MessageKind) -> &'static str {
    kind.type_hash()
}
