//! zenoh for the node's inputs and outputs: sessions that stay on loopback unless told
//! otherwise ([`session`]) and rmw_zenoh's conventions for the ROS 2 key mode ([`ros2`]).

pub mod ros2;
pub mod session;

pub use session::{open, TransportConfig, TransportError};
