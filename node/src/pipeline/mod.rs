//! The node's processing stages that need no transport: pairing left, right and pose by
//! timestamp ([`sync`]) and cutting the synchronised stream into bins ([`binner`]). The zenoh
//! side feeds them and the worker consumes what they emit, checking every bin's map
//! against its own stereo pair ([`self_check`]), with the operating point a latency budget
//! calls for ([`operating`]).

pub mod bin_map;
pub mod binner;
pub mod operating;
pub mod self_check;
pub mod sync;
pub mod worker;
