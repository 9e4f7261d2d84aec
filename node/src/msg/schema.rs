//! Complete message definitions in the `ros2msg` schema encoding, the text rosbag2 stores in
//! an MCAP schema record so that tools which do not know a type (Foxglove, the `mcap` CLI,
//! `rosbags`) can still decode its messages.
//!
//! The layout follows rosbag2's `LocalMessageDefinitionSource` (and the page on it,
//! its `docs/message_definition_encoding.md`): the type's own `.msg` text first, then
//! every type it depends on, transitively and each once, depth first, the dependencies of
//! one type in sorted name order; each dependency is preceded by a blank line, a line of 80
//! `=` and `MSG: pkg/Type`. The `.msg` texts are [`MessageKind::definition`]'s.

use std::collections::HashSet;

use super::type_hash::referenced_types;
use super::MessageKind;

/// The line that separates the definitions (80 `=` and a newline).
pub const DELIMITER: &str =
    "================================================================================\n";

/// The complete `ros2msg` definition of `kind`: its `.msg` text and those of every type it
/// uses, as rosbag2 writes it into an MCAP schema.
pub fn ros2msg(kind: MessageKind) -> String {
    let mut out = String::new();
    append(kind, &mut HashSet::new(), &mut out);
    out
}

/// Appends the definition of `kind` and then of each of its dependencies not in `seen`.
fn append(kind: MessageKind, seen: &mut HashSet<MessageKind>, out: &mut String) {
    out.push_str(kind.definition());
    // The definitions are constants of `kind.rs`; the tests below expand every kind.
    let mut dependencies: Vec<(String, MessageKind)> =
        referenced_types(kind.ros_name(), kind.definition())
            .expect("the built-in message definitions parse")
            .iter()
            .map(|name| {
                let dependency = MessageKind::from_ros_name(name)
                    .expect("built-in messages only use built-in messages");
                (name.replacen("/msg/", "/", 1), dependency)
            })
            .collect();
    dependencies.sort_by(|a, b| a.0.cmp(&b.0));
    for (name, dependency) in dependencies {
        if seen.insert(dependency) {
            out.push('\n');
            out.push_str(DELIMITER);
            out.push_str("MSG: ");
            out.push_str(&name);
            out.push('\n');
            append(dependency, seen, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_stamped_lists_each_dependency_once_depth_first() {
        let expected = format!(
            "std_msgs/Header header\nPose pose\n\n{DELIMITER}MSG: geometry_msgs/Pose\n\
             Point position\nQuaternion orientation\n\n{DELIMITER}MSG: geometry_msgs/Point\n\
             float64 x\nfloat64 y\nfloat64 z\n\n{DELIMITER}MSG: geometry_msgs/Quaternion\n\
             float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n\n{DELIMITER}\
             MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\n\
             {DELIMITER}MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
        );
        assert_eq!(ros2msg(MessageKind::PoseStamped), expected);
    }

    #[test]
    fn every_kind_expands_and_names_each_type_once() {
        for kind in MessageKind::ALL {
            let text = ros2msg(kind);
            assert!(text.starts_with(kind.definition()), "{kind:?}");
            let names: Vec<&str> = text
                .lines()
                .filter_map(|l| l.strip_prefix("MSG: "))
                .collect();
            let unique: HashSet<&str> = names.iter().copied().collect();
            assert_eq!(names.len(), unique.len(), "{kind:?}: {names:?}");
        }
        // MapUpdate -> Header -> Time, PointCloud2 -> PointField (Header already listed).
        let map_update = ros2msg(MessageKind::MapUpdate);
        assert_eq!(map_update.matches("MSG: ").count(), 4, "{map_update}");
        assert_eq!(
            ros2msg(MessageKind::BinLatency),
            MessageKind::BinLatency.definition()
        );
    }
}
