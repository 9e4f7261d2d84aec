//! Why the node stopped with an error. Bad input never stops it: a malformed message is
//! counted and reported on the diagnostics topic instead.

use crate::store::map_files::{ExportError, RestoreError};
use crate::transport::TransportError;

/// Why the node stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    /// The zenoh session.
    #[error(transparent)]
    Transport(#[from] TransportError),
    /// The method name.
    #[error(transparent)]
    Method(#[from] model::methods::MethodError),
    /// The fusion settings.
    #[error(transparent)]
    Fusion(#[from] crate::fusion::FusionError),
    /// Declaring the publishers (a bad node name) or publishing.
    #[error(transparent)]
    Outlet(#[from] crate::transport::OutletError),
    /// Writing the exports.
    #[error(transparent)]
    Export(#[from] ExportError),
    /// The out folder's checkpoint cannot be resumed.
    #[error(transparent)]
    Restore(#[from] RestoreError),
    /// The map's journal could not be set up in the out folder.
    #[error("the global map's journal: {0}")]
    Journal(#[from] crate::fusion::StoreError),
    /// The node's weights could not be read to fingerprint them for its workers.
    #[error(transparent)]
    Fingerprint(#[from] crate::remote::FingerprintError),
    /// The Foxglove server did not start (`run --foxglove`).
    #[error(transparent)]
    Foxglove(#[from] crate::foxglove::FoxgloveError),
    /// The pose source's settings (`run --pose-source`).
    #[error(transparent)]
    PoseSource(#[from] crate::tf::PoseSourceError),
    /// The thread that returns freed memory to the system did not start.
    #[error("starting the memory-release thread: {0}")]
    MemoryRelease(#[source] std::io::Error),
}
