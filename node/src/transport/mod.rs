//! zenoh for the node's inputs and outputs: the node's topics and their keys ([`keys`]),
//! sessions that stay on loopback unless told otherwise ([`session`]), why that can fail
//! ([`error`]), what an endpoint exposes and the secure profile ([`security`]), rmw_zenoh's
//! conventions for the ROS 2 key mode ([`ros2`]), and the publishing side that uses them
//! ([`outlet`]).

#[cfg(feature = "runtime")]
pub mod error;
pub mod keys;
#[cfg(feature = "runtime")]
pub mod outlet;
pub mod ros2;
#[cfg(feature = "runtime")]
pub mod security;
#[cfg(feature = "runtime")]
pub mod session;

#[cfg(feature = "runtime")]
pub use error::TransportError;
pub use keys::Keys;
#[cfg(feature = "runtime")]
pub use outlet::{Outlet, OutletError};
#[cfg(feature = "runtime")]
pub use security::{Reach, TlsFiles};
#[cfg(feature = "runtime")]
pub use session::{open, TransportConfig};
