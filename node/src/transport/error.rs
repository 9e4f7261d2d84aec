//! Why a zenoh session could not be opened or used: the one error type of the transport,
//! shared by the session and its security checks.

use std::path::PathBuf;

/// Why a session could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// The config file or a flag was rejected by zenoh.
    #[error("zenoh configuration: {0}")]
    Config(String),
    /// A file the configuration names could not be read.
    #[error("zenoh configuration: reading {}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A plain endpoint while the secure profile is on: its traffic would be neither
    /// encrypted nor authenticated.
    #[error("{endpoint} is not encrypted but TLS is on: use tls/ (or quic/) endpoints")]
    Unencrypted {
        /// The endpoint.
        endpoint: String,
    },
    /// zenoh failed to open the session (an endpoint in use, a bad certificate).
    #[error("opening the zenoh session (listening on {listen})")]
    Open {
        /// The listen endpoints asked for.
        listen: String,
        /// zenoh's reason.
        #[source]
        source: zenoh::Error,
    },
    /// Publishing or subscribing failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
}

impl From<zenoh::Error> for TransportError {
    /// A failure to publish, subscribe or query, in zenoh's words.
    fn from(e: zenoh::Error) -> Self {
        TransportError::Zenoh(e.to_string())
    }
}
