//! What a session exposes and how to lock it down. The node listens on loopback unless an
//! endpoint says otherwise ([`loopback_default`]); an endpoint that other machines can reach
//! is classified ([`reach`]) and warned about ([`exposure_warning`]); the secure profile is
//! zenoh's TLS with mutual authentication ([`TlsFiles`]) plus zenoh's access control, read
//! from a file ([`access_control_json5`]).

use std::net::IpAddr;
use std::path::{Path, PathBuf};

use zenoh::Config;

use super::error::TransportError;

/// Who can reach a listen endpoint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reach {
    /// A local IPC endpoint (a unix socket or pipe): no network at all.
    Local,
    /// A loopback address (127.0.0.0/8, ::1, `localhost`): this machine only.
    Loopback,
    /// The unspecified address (0.0.0.0, ::): every interface, so every network the machine
    /// is on.
    AllInterfaces,
    /// Any other address or host name (a LAN address, a public one, a name that may resolve
    /// to either): reachable from other machines.
    Network,
}

impl Reach {
    /// Whether other machines can connect to an endpoint with this reach.
    pub fn is_exposed(self) -> bool {
        matches!(self, Reach::AllInterfaces | Reach::Network)
    }
}

/// Classifies a zenoh endpoint (`proto/address[?metadata][#config]`) by who can reach it,
/// from its text alone: no name is resolved and nothing is bound.
pub fn reach(endpoint: &str) -> Reach {
    let locator = endpoint.split(['?', '#']).next().unwrap_or_default();
    let Some((proto, address)) = locator.split_once('/') else {
        return Reach::Network;
    };
    if matches!(proto, "unixsock-stream" | "unixpipe") {
        return Reach::Local;
    }
    let host = match address.strip_prefix('[') {
        Some(rest) => rest.split(']').next().unwrap_or_default(),
        None => address.rsplit_once(':').map_or(address, |(h, _)| h),
    };
    match host.parse::<IpAddr>() {
        Ok(ip) if ip.is_unspecified() => Reach::AllInterfaces,
        Ok(ip) if ip.to_canonical().is_loopback() => Reach::Loopback,
        Ok(_) => Reach::Network,
        Err(_) if host.eq_ignore_ascii_case("localhost") => Reach::Loopback,
        Err(_) => Reach::Network,
    }
}

/// The warning printed for a listen endpoint other machines can reach (`None` for a
/// loopback or local one). It says whether the secure profile is on, since without it
/// anyone who reaches the port can publish inputs and read every output.
pub fn exposure_warning(endpoint: &str, tls: bool) -> Option<String> {
    let whom = match reach(endpoint) {
        Reach::Local | Reach::Loopback => return None,
        Reach::AllInterfaces => "every network interface",
        Reach::Network => "a non-loopback address",
    };
    let guard = match tls {
        true => "peers must present a certificate signed by the --tls-ca authority",
        false => {
            "without TLS (--tls-ca/--tls-cert/--tls-key) any machine that reaches it can \
             publish inputs and read every output"
        }
    };
    Some(format!(
        "warning: listening on {endpoint}, {whom}: {guard}; see docs/security.md, \"Defaults: loopback only\""
    ))
}

/// The listen endpoint used when none is given: loopback, on a random port for a peer (as
/// zenoh's own peer default, `tcp/[::]:0`, but not on every interface) and zenoh's port 7447
/// for a router. `tls/` instead of `tcp/` when the secure profile is on.
pub fn loopback_default(tls: bool) -> String {
    let proto = if tls { "tls" } else { "tcp" };
    format!(r#"{{ router: ["{proto}/127.0.0.1:7447"], peer: ["{proto}/127.0.0.1:0"] }}"#)
}

/// The secure profile's certificate files, PEM: one identity per process, used both when it
/// listens and when it connects, with mutual authentication (each side checks the other's
/// certificate against the same authority).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TlsFiles {
    /// The certificate authority every peer's certificate must be signed by.
    pub ca: PathBuf,
    /// This process's certificate (its common name is what access control rules name).
    pub cert: PathBuf,
    /// This process's private key.
    pub key: PathBuf,
}

impl TlsFiles {
    /// Sets zenoh's `transport/link/tls` section from these files (each must be readable:
    /// zenoh would otherwise only fail when a link opens, naming no file).
    pub fn apply(&self, config: &mut Config) -> Result<(), TransportError> {
        for path in [&self.ca, &self.cert, &self.key] {
            std::fs::metadata(path).map_err(|source| TransportError::File {
                path: path.clone(),
                source,
            })?;
        }
        let file = |path: &PathBuf| match path.to_str() {
            Some(text) => Ok(serde_json::Value::from(text)),
            None => Err(TransportError::Config(format!(
                "{}: the path is not UTF-8",
                path.display()
            ))),
        };
        let settings = [
            ("root_ca_certificate", file(&self.ca)?),
            ("listen_certificate", file(&self.cert)?),
            ("listen_private_key", file(&self.key)?),
            ("connect_certificate", file(&self.cert)?),
            ("connect_private_key", file(&self.key)?),
            ("enable_mtls", true.into()),
            ("verify_name_on_connect", true.into()),
        ];
        for (key, value) in settings {
            config
                .insert_json5(&format!("transport/link/tls/{key}"), &value.to_string())
                .map_err(|e| TransportError::Config(format!("transport/link/tls/{key}: {e}")))?;
        }
        Ok(())
    }
}

/// Whether an endpoint encrypts its traffic (TLS over TCP, or QUIC).
pub fn is_encrypted(endpoint: &str) -> bool {
    endpoint.starts_with("tls/") || endpoint.starts_with("quic/")
}

/// The text of an access control file: zenoh's `access_control` object (JSON5: `enabled`,
/// `default_permission`, `rules`, `subjects`, `policies`), as in `launch/zenoh_acl.json5`.
pub fn access_control_json5(path: &Path) -> Result<String, TransportError> {
    std::fs::read_to_string(path).map_err(|source| TransportError::File {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_are_classified_by_their_address() {
        let cases = [
            ("tcp/127.0.0.1:7447", Reach::Loopback),
            ("tcp/127.0.0.1:0", Reach::Loopback),
            ("tls/127.3.2.1:7447", Reach::Loopback),
            ("tcp/[::1]:7447", Reach::Loopback),
            ("tcp/[::ffff:127.0.0.1]:7447", Reach::Loopback),
            ("tcp/localhost:7447", Reach::Loopback),
            ("tcp/LOCALHOST:7447#iface=lo", Reach::Loopback),
            ("unixsock-stream//tmp/node.sock", Reach::Local),
            ("tcp/0.0.0.0:7447", Reach::AllInterfaces),
            ("tcp/[::]:0", Reach::AllInterfaces),
            ("udp/0.0.0.0:7447?rel=0", Reach::AllInterfaces),
            ("tcp/192.168.1.20:7447", Reach::Network),
            ("tcp/10.0.0.5:7447#iface=eth0", Reach::Network),
            ("tcp/[fe80::1]:7447", Reach::Network),
            ("tls/node.example.org:7447", Reach::Network),
            ("nonsense", Reach::Network),
        ];
        for (endpoint, want) in cases {
            assert_eq!(reach(endpoint), want, "{endpoint}");
        }
    }

    #[test]
    fn only_exposed_endpoints_are_warned_about() {
        assert_eq!(exposure_warning("tcp/127.0.0.1:7447", false), None);
        assert_eq!(exposure_warning("unixsock-stream//tmp/n.sock", false), None);
        let all = exposure_warning("tcp/0.0.0.0:7447", false).unwrap();
        assert!(
            all.starts_with("warning: listening on tcp/0.0.0.0:7447"),
            "{all}"
        );
        assert!(all.contains("every network interface"), "{all}");
        assert!(all.contains("any machine that reaches it"), "{all}");
        let lan = exposure_warning("tls/192.168.1.20:7447", true).unwrap();
        assert!(lan.contains("a non-loopback address"), "{lan}");
        assert!(lan.contains("must present a certificate"), "{lan}");
    }

    #[test]
    fn encryption_is_read_from_the_protocol() {
        assert!(is_encrypted("tls/127.0.0.1:7447"));
        assert!(is_encrypted("quic/127.0.0.1:7447"));
        assert!(!is_encrypted("tcp/127.0.0.1:7447"));
        assert!(!is_encrypted("ws/127.0.0.1:7447"));
    }
}
