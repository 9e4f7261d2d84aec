//! Opening a zenoh session the way the node wants it by default: peer mode, no multicast or
//! gossip scouting (nothing leaves the machine unless an endpoint says so), explicit listen
//! and connect endpoints, and with none given a listener on loopback only (zenoh's own default
//! is every interface). A zenoh config file, when given, is the base and the flags refine it;
//! `client` mode with a `connect` endpoint uses a zenoh router instead. The secure profile
//! (TLS with mutual authentication, access control) is in [`super::security`].

use std::path::PathBuf;

use zenoh::{Config, Session};

use super::error::TransportError;
use super::security::{self, TlsFiles};

/// How to reach the other processes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TransportConfig {
    /// A zenoh JSON5 config file to start from (flags below override its fields).
    pub config_file: Option<PathBuf>,
    /// `peer` (default) or `client` (through a router).
    pub mode: String,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:7447`; none: loopback on a random port
    /// (unless the config file names some).
    pub listen: Vec<String>,
    /// Endpoints to connect to.
    pub connect: Vec<String>,
    /// Multicast scouting (off by default: loopback only).
    pub multicast_scouting: bool,
    /// TLS with mutual authentication on every link (then every endpoint must be `tls/` or
    /// `quic/`).
    pub tls: Option<TlsFiles>,
    /// A file holding zenoh's `access_control` object: which peers may publish and subscribe
    /// to which keys.
    pub access_control: Option<PathBuf>,
}

impl Default for TransportConfig {
    fn default() -> Self {
        Self {
            config_file: None,
            mode: "peer".into(),
            listen: Vec::new(),
            connect: Vec::new(),
            multicast_scouting: false,
            tls: None,
            access_control: None,
        }
    }
}

impl TransportConfig {
    /// The zenoh config this describes.
    pub fn zenoh_config(&self) -> Result<Config, TransportError> {
        let mut config = match &self.config_file {
            Some(path) => Config::from_file(path)
                .map_err(|e| TransportError::Config(format!("{}: {e}", path.display())))?,
            None => Config::default(),
        };
        insert(&mut config, "mode", &json(&self.mode))?;
        let scouting = json(&self.multicast_scouting);
        insert(&mut config, "scouting/multicast/enabled", &scouting)?;
        insert(&mut config, "scouting/gossip/enabled", &scouting)?;
        if !self.listen.is_empty() {
            insert(&mut config, "listen/endpoints", &json(&self.listen))?;
        } else if listen_is_zenoh_default(&config)? {
            let default = security::loopback_default(self.tls.is_some());
            insert(&mut config, "listen/endpoints", &default)?;
        }
        if !self.connect.is_empty() {
            insert(&mut config, "connect/endpoints", &json(&self.connect))?;
        }
        if let Some(tls) = &self.tls {
            let mut endpoints = self.listen.iter().chain(&self.connect);
            if let Some(e) = endpoints.find(|e| !security::is_encrypted(e)) {
                return Err(TransportError::Unencrypted {
                    endpoint: e.clone(),
                });
            }
            tls.apply(&mut config)?;
        }
        if let Some(path) = &self.access_control {
            let acl = security::access_control_json5(path)?;
            insert(&mut config, "access_control", &acl)
                .map_err(|e| TransportError::Config(format!("{}: {e}", path.display())))?;
        }
        Ok(config)
    }

    /// The warnings for the listen endpoints of this configuration that other machines can
    /// reach (none for the default, loopback).
    pub fn exposure_warnings(&self) -> Result<Vec<String>, TransportError> {
        let config = self.zenoh_config()?;
        let mtls = config.get_json("transport/link/tls/enable_mtls").ok() == Some("true".into());
        Ok(listen_endpoints(&config)?
            .iter()
            .filter_map(|e| security::exposure_warning(e, mtls && security::is_encrypted(e)))
            .collect())
    }
}

/// Opens a session as `config` says, first printing a warning on stderr for every listen
/// endpoint other machines can reach.
pub async fn open(config: &TransportConfig) -> Result<Session, TransportError> {
    for warning in config.exposure_warnings()? {
        eprintln!("{warning}");
    }
    let zenoh_config = config.zenoh_config()?;
    let listen = match listen_endpoints(&zenoh_config)? {
        none if none.is_empty() => "nothing".to_string(),
        some => some.join(", "),
    };
    zenoh::open(zenoh_config)
        .await
        .map_err(|source| TransportError::Open { listen, source })
}

/// The listen endpoints `config` uses in its mode (zenoh's mode-dependent lists resolved).
pub fn listen_endpoints(config: &Config) -> Result<Vec<String>, TransportError> {
    let get = |key: &str| -> Result<serde_json::Value, TransportError> {
        let text = config
            .get_json(key)
            .map_err(|e| TransportError::Config(format!("{key}: {e}")))?;
        serde_json::from_str(&text).map_err(|e| TransportError::Config(format!("{key}: {e}")))
    };
    let mode = get("mode")?;
    let mode = mode.as_str().unwrap_or("peer");
    let endpoints = match get("listen/endpoints")? {
        serde_json::Value::Object(by_mode) => by_mode.get(mode).cloned().unwrap_or_default(),
        other => other,
    };
    Ok(endpoints
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|e| e.as_str().map(str::to_string))
        .collect())
}

/// Whether `config`'s listen endpoints are still zenoh's built-in ones (every interface):
/// no flag and no config file chose any.
fn listen_is_zenoh_default(config: &Config) -> Result<bool, TransportError> {
    let key = "listen/endpoints";
    let ours = config.get_json(key);
    let zenohs = Config::default().get_json(key);
    match (ours, zenohs) {
        (Ok(ours), Ok(zenohs)) => Ok(ours == zenohs),
        (Err(e), _) | (_, Err(e)) => Err(TransportError::Config(format!("{key}: {e}"))),
    }
}

/// Sets `key` to the JSON5 `value`.
fn insert(config: &mut Config, key: &str, value: &str) -> Result<(), TransportError> {
    config
        .insert_json5(key, value)
        .map_err(|e| TransportError::Config(format!("{key}: {e}")))
}

/// A plain value as JSON5 text for `insert_json5`.
fn json(v: &impl serde::Serialize) -> String {
    serde_json::to_string(v).expect("strings, bools and string lists always serialise")
}
