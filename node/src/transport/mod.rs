//! zenoh for the node's inputs and outputs: sessions that stay on loopback unless told
//! otherwise ([`session`]), rmw_zenoh's conventions for the ROS 2 key mode ([`ros2`]), and
//! the publishing side that uses them ([`outlet`]).

pub mod outlet;
pub mod ros2;
pub mod session;

pub use outlet::{Outlet, OutletError};
pub use session::{open, TransportConfig, TransportError};
