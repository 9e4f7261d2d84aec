//! The `offered_qos_profiles` channel metadata of rosbag2's MCAP files: the QoS profiles of
//! a topic's publishers as YAML, in the form rosbag2 Jazzy writes (metadata version 9:
//! `rosbag2_storage/src/rosbag2_storage/qos.cpp`, `serialize_rclcpp_qos_vector`, read from
//! ros2/rosbag2 and written anew): a YAML list with one map per publisher, keys in the
//! order `history, depth, reliability, durability, deadline, lifespan, liveliness,
//! liveliness_lease_duration, avoid_ros_namespace_conventions`, policies as `rmw`'s names
//! (`keep_last`, `reliable`, `transient_local`, `automatic`, ...), durations as
//! `{sec, nsec}` maps, as yaml-cpp's `YAML::Dump` lays them out (block style, two-space
//! indents, no final newline). `ros2 bag play` offers these profiles again on replay.

use crate::transport::ros2::{Durability, History, Qos, Reliability};

/// `RMW_DURATION_INFINITE` as rosbag2 writes it: `{sec: 9223372036, nsec: 854775807}`.
const INFINITE: (u64, u64) = (9_223_372_036, 854_775_807);

/// The YAML list of rosbag2's `offered_qos_profiles` for one publisher offering `qos`
/// (deadline, lifespan and liveliness lease infinite, liveliness automatic, ROS namespace
/// conventions kept: what rclcpp publishes with unless told otherwise).
pub fn offered_qos_profiles(qos: &Qos) -> String {
    let (history, depth) = match qos.history {
        History::KeepLast(depth) => ("keep_last", depth),
        History::KeepAll => ("keep_all", 0),
    };
    let reliability = match qos.reliability {
        Reliability::Reliable => "reliable",
        Reliability::BestEffort => "best_effort",
    };
    let durability = match qos.durability {
        Durability::Volatile => "volatile",
        Durability::TransientLocal => "transient_local",
    };
    let duration = |name: &str| {
        format!(
            "  {name}:\n    sec: {}\n    nsec: {}\n",
            INFINITE.0, INFINITE.1
        )
    };
    format!(
        "- history: {history}\n  depth: {depth}\n  reliability: {reliability}\n  \
         durability: {durability}\n{}{}  liveliness: automatic\n{}  \
         avoid_ros_namespace_conventions: false",
        duration("deadline"),
        duration("lifespan"),
        duration("liveliness_lease_duration"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_static_transform_profile_reads_as_rosbag2_writes_it() {
        let qos = Qos {
            reliability: Reliability::Reliable,
            durability: Durability::TransientLocal,
            history: History::KeepLast(1),
        };
        let want = "- history: keep_last\n  depth: 1\n  reliability: reliable\n  \
                    durability: transient_local\n  deadline:\n    sec: 9223372036\n    \
                    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n    nsec: 854775807\n  \
                    liveliness: automatic\n  liveliness_lease_duration:\n    sec: 9223372036\n    \
                    nsec: 854775807\n  avoid_ros_namespace_conventions: false";
        assert_eq!(offered_qos_profiles(&qos), want);
    }
}
