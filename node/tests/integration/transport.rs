//! Real zenoh sessions on loopback: the node's default configuration (peer mode, scouting
//! off, explicit endpoints) connects two sessions and carries samples in order.

use crate::net_support;

use std::time::Duration;

use node::transport::TransportConfig;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_loopback_peers_exchange_samples_in_order() {
    let (a, b) = net_support::connected_pair().await;
    let sub = a.declare_subscriber("test/ns/**").await.unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let publisher = b.declare_publisher("test/ns/data").await.unwrap();
    for k in 0u32..50 {
        publisher.put(k.to_le_bytes().to_vec()).await.unwrap();
    }
    for k in 0u32..50 {
        let sample = tokio::time::timeout(Duration::from_secs(5), sub.recv_async())
            .await
            .expect("sample within 5 s")
            .unwrap();
        assert_eq!(sample.key_expr().as_str(), "test/ns/data");
        assert_eq!(sample.payload().to_bytes().as_ref(), &k.to_le_bytes());
    }
}

#[test]
fn a_bad_config_file_is_a_typed_error() {
    let path = std::env::temp_dir().join(format!("bad-zenoh-{}.json5", std::process::id()));
    std::fs::write(&path, "{ mode: 42 ").unwrap();
    let err = TransportConfig {
        config_file: Some(path.clone()),
        ..TransportConfig::default()
    }
    .zenoh_config()
    .unwrap_err();
    assert!(
        err.to_string().contains(&path.display().to_string()),
        "{err}"
    );
    let _ = std::fs::remove_file(path);
}
