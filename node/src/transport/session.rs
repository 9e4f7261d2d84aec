//! Opening a zenoh session the way the node wants it by default: peer mode, no multicast or
//! gossip scouting (nothing leaves the machine unless an endpoint says so), explicit listen
//! and connect endpoints. A zenoh config file, when given, is the base and the flags refine it;
//! `client` mode with a `connect` endpoint uses a zenoh router instead.

use std::path::PathBuf;

use zenoh::{Config, Session};

/// How to reach the other processes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TransportConfig {
    /// A zenoh JSON5 config file to start from (flags below override its fields).
    pub config_file: Option<PathBuf>,
    /// `peer` (default) or `client` (through a router).
    pub mode: String,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:7447`.
    pub listen: Vec<String>,
    /// Endpoints to connect to.
    pub connect: Vec<String>,
    /// Multicast scouting (off by default: loopback only).
    pub multicast_scouting: bool,
}

impl Default for TransportConfig {
    fn default() -> Self {
        Self {
            config_file: None,
            mode: "peer".into(),
            listen: Vec::new(),
            connect: Vec::new(),
            multicast_scouting: false,
        }
    }
}

/// Why a session could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// The config file or a flag was rejected by zenoh.
    #[error("zenoh configuration: {0}")]
    Config(String),
    /// zenoh failed to open the session (an endpoint in use, unreachable).
    #[error("opening the zenoh session: {0}")]
    Open(String),
    /// Publishing or subscribing failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
}

impl TransportConfig {
    /// The zenoh config this describes.
    pub fn zenoh_config(&self) -> Result<Config, TransportError> {
        let cfg_err = |e: zenoh::Error| TransportError::Config(e.to_string());
        let mut config = match &self.config_file {
            Some(path) => Config::from_file(path)
                .map_err(|e| TransportError::Config(format!("{}: {e}", path.display())))?,
            None => Config::default(),
        };
        config
            .insert_json5("mode", &json(&self.mode))
            .map_err(cfg_err)?;
        config
            .insert_json5(
                "scouting/multicast/enabled",
                &json(&self.multicast_scouting),
            )
            .map_err(cfg_err)?;
        config
            .insert_json5("scouting/gossip/enabled", &json(&self.multicast_scouting))
            .map_err(cfg_err)?;
        if !self.listen.is_empty() {
            config
                .insert_json5("listen/endpoints", &json(&self.listen))
                .map_err(cfg_err)?;
        }
        if !self.connect.is_empty() {
            config
                .insert_json5("connect/endpoints", &json(&self.connect))
                .map_err(cfg_err)?;
        }
        Ok(config)
    }
}

/// Opens a session as `config` says.
pub async fn open(config: &TransportConfig) -> Result<Session, TransportError> {
    zenoh::open(config.zenoh_config()?)
        .await
        .map_err(|e| TransportError::Open(e.to_string()))
}

/// A plain value as JSON5 text for `insert_json5`.
fn json(v: &impl serde::Serialize) -> String {
    serde_json::to_string(v).expect("strings, bools and string lists always serialise")
}
