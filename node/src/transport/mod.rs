//! zenoh for the node's inputs and outputs: sessions that stay on loopback unless told
//! otherwise ([`session`]).

pub mod session;

pub use session::{open, TransportConfig, TransportError};
