//! The zenoh flags every networked subcommand shares (`run`, `replay`, `record`, `monitor`,
//! `view`, ...): where to listen and connect, the key mode, and the secure profile.
//! Default: peer mode, loopback only.

use std::path::PathBuf;

use clap::Args;

use crate::transport::keys::KeyMode;
use crate::transport::Keys;
use crate::transport::{TlsFiles, TransportConfig};

/// zenoh flags shared by the node's commands. Default: peer mode, loopback only.
#[derive(Args, Clone, Debug)]
#[command(next_help_heading = "Zenoh")]
pub struct ZenohArgs {
    /// A zenoh JSON5 config file to start from (the flags below override it).
    #[arg(long, env = "STEREOSPLAT_ZENOH_CONFIG")]
    zenoh_config: Option<PathBuf>,
    /// Endpoints to listen on (repeatable), e.g. tcp/127.0.0.1:7447. None: loopback on a
    /// random port. A non-loopback address (0.0.0.0, ::, a LAN address) prints a warning.
    #[arg(long)]
    listen: Vec<String>,
    /// Endpoints to connect to (repeatable).
    #[arg(long)]
    connect: Vec<String>,
    /// `peer` or `client` (through a zenoh router).
    #[arg(long, default_value = "peer")]
    mode: String,
    /// Namespace of every key.
    #[arg(long, default_value = "stereosplat")]
    namespace: String,
    /// Key mode: `plain` (`<ns>/<topic>`) or `ros2` (rmw_zenoh's keys, attachments and
    /// liveliness tokens, so ROS 2 nodes on rmw_zenoh see the topics).
    #[arg(long, value_enum, default_value_t = KeyModeArg::Plain)]
    key_mode: KeyModeArg,
    /// ROS domain id of the ros2 key mode.
    #[arg(long, env = "ROS_DOMAIN_ID", default_value_t = 0)]
    domain_id: u32,
    /// Secure profile: the certificate authority (PEM) every peer's certificate must be
    /// signed by; with --tls-cert and --tls-key, every link is TLS with mutual
    /// authentication and every endpoint must be tls/.
    #[arg(long, requires_all = ["tls_cert", "tls_key"])]
    tls_ca: Option<PathBuf>,
    /// Secure profile: this process's certificate (PEM), signed by --tls-ca.
    #[arg(long, requires = "tls_ca")]
    tls_cert: Option<PathBuf>,
    /// Secure profile: this process's private key (PEM).
    #[arg(long, requires = "tls_ca")]
    tls_key: Option<PathBuf>,
    /// Secure profile: zenoh access control rules (JSON5, zenoh's `access_control` object;
    /// see launch/zenoh_acl.json5): which certificate names may publish or subscribe to
    /// which keys.
    #[arg(long)]
    acl: Option<PathBuf>,
}

/// `--key-mode` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum KeyModeArg {
    /// `<ns>/<topic>`.
    Plain,
    /// rmw_zenoh-compatible.
    Ros2,
}

impl ZenohArgs {
    /// The transport these flags describe.
    pub(crate) fn transport(&self) -> TransportConfig {
        TransportConfig {
            config_file: self.zenoh_config.clone(),
            mode: self.mode.clone(),
            listen: self.listen.clone(),
            connect: self.connect.clone(),
            multicast_scouting: false,
            tls: match (&self.tls_ca, &self.tls_cert, &self.tls_key) {
                (Some(ca), Some(cert), Some(key)) => Some(TlsFiles {
                    ca: ca.clone(),
                    cert: cert.clone(),
                    key: key.clone(),
                }),
                _ => None,
            },
            access_control: self.acl.clone(),
        }
    }

    /// The keys these flags name.
    pub fn keys(&self) -> Keys {
        let mode = match self.key_mode {
            KeyModeArg::Plain => KeyMode::Plain,
            KeyModeArg::Ros2 => KeyMode::Ros2 {
                domain_id: self.domain_id,
            },
        };
        Keys::with_mode(&self.namespace, mode)
    }
}
