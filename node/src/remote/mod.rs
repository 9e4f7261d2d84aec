//! Bins on worker processes, on this machine or others, over the node's zenoh session:
//! the protocol ([`wire`]), what both ends compare before a bin changes hands
//! ([`fingerprint`]), the worker process ([`mod@serve`], `stereosplat worker`), and the node's
//! side: which bin runs where and the release of maps in bin order ([`dispatch`]), the
//! talking to the workers ([`pool`]), and what the node takes from their replies
//! ([`admit`]: a remote bin is the node's bin). docs/workers.md says how to run them.

pub mod admit;
pub mod dispatch;
pub mod fingerprint;
pub mod pool;
pub mod serve;
pub mod wire;

pub use admit::{Rejection, Rules};
pub use dispatch::{Answer, Assignment, Dispatch, Slot, MAX_ATTEMPTS};
pub use fingerprint::{Fingerprint, FingerprintError};
pub use pool::{Pool, PoolConfig, PoolEvent, MAX_GREETINGS, MAX_WORKERS};
pub use serve::{serve, ServeConfig, ServeError, ServeSummary};
