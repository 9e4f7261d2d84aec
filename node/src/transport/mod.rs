//! zenoh for the node's inputs and outputs: sessions that stay on loopback unless told
//! otherwise ([`session`]), what an endpoint exposes and the secure profile ([`security`]),
//! rmw_zenoh's conventions for the ROS 2 key mode ([`ros2`]), and the publishing side that
//! uses them ([`outlet`]).

pub mod outlet;
pub mod ros2;
pub mod security;
pub mod session;

pub use outlet::{Outlet, OutletError};
pub use security::{Reach, TlsFiles};
pub use session::{open, TransportConfig, TransportError};
