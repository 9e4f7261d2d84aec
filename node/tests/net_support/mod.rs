//! What the network tests share: a loopback port nothing listens on, and two connected
//! sessions (each test uses a part of it, hence the `dead_code` allowance).
#![allow(dead_code)]

use std::time::Duration;

use node::transport::{open, TransportConfig};
use zenoh::Session;

/// A TCP port on 127.0.0.1 that was free a moment ago (bound to port 0, then released).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Two sessions on loopback, the second connected to the first, returned once they see each
/// other (or after 5 s): (listening side, connecting side).
pub async fn connected_pair() -> (Session, Session) {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let a = open(&TransportConfig {
        listen: vec![endpoint.clone()],
        ..TransportConfig::default()
    })
    .await
    .unwrap();
    let b = open(&TransportConfig {
        connect: vec![endpoint],
        ..TransportConfig::default()
    })
    .await
    .unwrap();
    for _ in 0..250 {
        if !a.info().peers_zid().await.collect::<Vec<_>>().is_empty() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    (a, b)
}
