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

/// Waits (two minutes at most) until a publisher of `session` on `key` has a matching
/// subscriber: what a test waits for before it publishes what a subscriber must receive.
pub async fn sees_a_subscriber(session: &Session, key: &str) -> bool {
    let publisher = session.declare_publisher(key.to_string()).await.unwrap();
    let start = std::time::Instant::now();
    while start.elapsed() < Duration::from_secs(120) {
        if publisher.matching_status().await.unwrap().matching() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    false
}

/// GET `path` from 127.0.0.1:`port` on a fresh connection: the status and the body (`None`
/// when the exchange fails).
pub fn http_get(port: u16, path: &str) -> Option<(u16, Vec<u8>)> {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(("127.0.0.1", port)).ok()?;
    stream.set_read_timeout(Some(Duration::from_secs(5))).ok()?;
    write!(stream, "GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").ok()?;
    let mut response = Vec::new();
    stream.read_to_end(&mut response).ok()?;
    let split = response.windows(4).position(|w| w == b"\r\n\r\n")?;
    let head = std::str::from_utf8(&response[..split]).ok()?;
    let status = head.split(' ').nth(1)?.parse().ok()?;
    Some((status, response[split + 4..].to_vec()))
}

/// GET `path` from 127.0.0.1:`port` and parse a 200 answer's body as JSON (`None`
/// otherwise).
pub fn http_json(port: u16, path: &str) -> Option<serde_json::Value> {
    let (status, body) = http_get(port, path)?;
    (status == 200).then_some(())?;
    serde_json::from_slice(&body).ok()
}
