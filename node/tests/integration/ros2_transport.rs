//! The ROS 2 (rmw_zenoh) publishing side on real zenoh sessions over loopback: an `Outlet` in
//! ROS 2 mode publishes on rmw_zenoh's keys with its 33-byte attachment and announces the node
//! and its topics with liveliness tokens that go away with it; in plain mode it publishes on
//! plain keys with no attachment and no tokens.

use crate::net_support;

use std::time::Duration;

use node::transport::keys::{
    KeyMode, Keys, Topic, BIN_MAP, DIAGNOSTICS, LATENCY, LEFT_IMAGE, POSE,
};
use node::transport::ros2::{qos_string, Attachment, EntityKind, Qos, Token};
use node::transport::{open, Outlet, OutletError, TransportConfig};
use zenoh::sample::SampleKind;
use zenoh::Session;

const WAIT: Duration = Duration::from_secs(5);

/// The liveliness tokens under `@ros2_lv/**` that `session` sees now, sorted.
async fn live_tokens(session: &Session) -> Vec<String> {
    let replies = session
        .liveliness()
        .get("@ros2_lv/**")
        .timeout(Duration::from_secs(2))
        .await
        .unwrap();
    let mut keys = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        keys.push(reply.result().unwrap().key_expr().to_string());
    }
    keys.sort();
    keys
}

const PUBLISHES: [Topic; 3] = [BIN_MAP, LATENCY, DIAGNOSTICS];
const SUBSCRIBES: [Topic; 2] = [LEFT_IMAGE, POSE];

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ros2_outlet_publishes_on_rmw_zenoh_keys_with_attachments() {
    let (a, b) = net_support::connected_pair().await;
    let keys = Keys::with_mode("stereosplat", KeyMode::Ros2 { domain_id: 0 });
    let sub = b.declare_subscriber("0/**").await.unwrap();
    let outlet = Outlet::declare(&a, &keys, "stereosplat_node", &PUBLISHES, &SUBSCRIBES)
        .await
        .unwrap();
    for topic in [BIN_MAP, LATENCY] {
        assert!(net_support::sees_a_subscriber(&a, &keys.key(topic)).await);
    }

    let before = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as i64;
    for round in 0..3u8 {
        for topic in [BIN_MAP, LATENCY] {
            outlet.put(topic, vec![round, 1, 2, 3]).await.unwrap();
        }
    }
    let mut seen: Vec<(String, Attachment, u8)> = Vec::new();
    for _ in 0..6 {
        let sample = tokio::time::timeout(WAIT, sub.recv_async())
            .await
            .expect("sample within 5 s")
            .unwrap();
        let attachment = sample.attachment().expect("every sample has an attachment");
        let bytes = attachment.to_bytes();
        assert_eq!(bytes.len(), 33);
        let attachment = Attachment::decode(&bytes).unwrap();
        let payload = sample.payload().to_bytes();
        seen.push((sample.key_expr().to_string(), attachment, payload[0]));
    }
    for topic in [BIN_MAP, LATENCY] {
        let key = keys.key(topic);
        assert!(key.starts_with(&format!(
            "0/stereosplat/{}/{}/RIHS01_",
            topic.name,
            topic.kind.dds_type_name()
        )));
        let mine: Vec<_> = seen.iter().filter(|(k, _, _)| *k == key).collect();
        let sequences: Vec<i64> = mine.iter().map(|(_, a, _)| a.sequence).collect();
        assert_eq!(sequences, [1, 2, 3], "{key}");
        let rounds: Vec<u8> = mine.iter().map(|(_, _, r)| *r).collect();
        assert_eq!(rounds, [0, 1, 2]);
        let gid = outlet.gid(topic).unwrap();
        assert!(mine.iter().all(|(_, a, _)| a.gid == gid), "stable GID");
        assert!(mine.iter().all(|(_, a, _)| a.source_timestamp_ns >= before));
    }
    assert_ne!(outlet.gid(BIN_MAP), outlet.gid(LATENCY));

    assert!(matches!(
        outlet.put(LEFT_IMAGE, vec![0]).await,
        Err(OutletError::NotDeclared("left/image"))
    ));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ros2_outlet_announces_node_and_topics_until_dropped() {
    let (a, b) = net_support::connected_pair().await;
    let keys = Keys::with_mode("stereosplat", KeyMode::Ros2 { domain_id: 3 });
    let watcher = b
        .liveliness()
        .declare_subscriber("@ros2_lv/3/**")
        .await
        .unwrap();
    let outlet = Outlet::declare(&a, &keys, "stereosplat_node", &PUBLISHES, &SUBSCRIBES)
        .await
        .unwrap();
    assert_eq!(outlet.token_keys().len(), 1 + 3 + 2);

    let mut expected: Vec<String> = outlet.token_keys().to_vec();
    expected.sort();
    // The tokens reach the other session in their own time: asked until all are there.
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    let mut live = live_tokens(&b).await;
    while live != expected && std::time::Instant::now() < deadline {
        live = live_tokens(&b).await;
    }
    assert_eq!(live, expected);

    let zid = a.zid().to_string();
    let tokens: Vec<Token> = live.iter().map(|k| Token::parse(k).unwrap()).collect();
    let node_id = tokens[0].node.node_id;
    let mut ids = Vec::new();
    for token in &tokens {
        assert_eq!(token.node.domain_id, 3);
        assert_eq!(token.node.zid, zid);
        assert_eq!(token.node.node_id, node_id);
        assert_eq!(token.node.enclave, "/");
        assert_eq!(token.node.namespace, "/stereosplat");
        assert_eq!(token.node.name, "stereosplat_node");
        ids.push(token.entity_id);
    }
    ids.sort();
    ids.dedup();
    assert_eq!(ids.len(), tokens.len(), "entity ids are unique");

    let of_kind = |kind| tokens.iter().filter(move |t| t.kind == kind);
    let nodes: Vec<_> = of_kind(EntityKind::Node).collect();
    assert_eq!(nodes.len(), 1);
    assert_eq!(nodes[0].entity_id, node_id);
    assert!(live.contains(&format!(
        "@ros2_lv/3/{zid}/{node_id}/{node_id}/NN/%/%stereosplat/stereosplat_node"
    )));
    for (kind, topics) in [
        (EntityKind::Publisher, &PUBLISHES[..]),
        (EntityKind::Subscription, &SUBSCRIBES[..]),
    ] {
        let mut names: Vec<String> = of_kind(kind)
            .map(|t| {
                let info = t.topic.as_ref().unwrap();
                let topic = topics
                    .iter()
                    .find(|x| info.name == format!("/stereosplat/{}", x.name))
                    .unwrap();
                assert_eq!(info.type_name, topic.kind.dds_type_name());
                assert_eq!(info.type_hash, topic.kind.type_hash());
                assert_eq!(info.qos, qos_string(&Qos::NODE));
                info.name.clone()
            })
            .collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), topics.len(), "{kind:?}");
    }
    // The publishers' GIDs are the hashes of their tokens.
    for topic in PUBLISHES {
        let token = of_kind(EntityKind::Publisher)
            .find(|t| t.topic.as_ref().unwrap().name == format!("/stereosplat/{}", topic.name))
            .unwrap();
        assert_eq!(outlet.gid(topic), Some(token.gid()));
    }

    drop(outlet);
    let mut deleted = Vec::new();
    while deleted.len() < expected.len() {
        let sample = tokio::time::timeout(WAIT, watcher.recv_async())
            .await
            .expect("token deletes within 5 s")
            .unwrap();
        if sample.kind() == SampleKind::Delete {
            deleted.push(sample.key_expr().to_string());
        }
    }
    deleted.sort();
    assert_eq!(deleted, expected);
    assert!(live_tokens(&b).await.is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plain_outlet_has_plain_keys_no_attachment_no_tokens() {
    let (a, b) = net_support::connected_pair().await;
    let keys = Keys::new("stereosplat");
    let sub = b.declare_subscriber("stereosplat/**").await.unwrap();
    let outlet = Outlet::declare(&a, &keys, "stereosplat_node", &PUBLISHES, &SUBSCRIBES)
        .await
        .unwrap();
    assert!(outlet.token_keys().is_empty());
    assert_eq!(outlet.gid(BIN_MAP), None);
    assert!(net_support::sees_a_subscriber(&a, &keys.key(DIAGNOSTICS)).await);
    outlet.put(DIAGNOSTICS, vec![7]).await.unwrap();
    let sample = tokio::time::timeout(WAIT, sub.recv_async())
        .await
        .expect("sample within 5 s")
        .unwrap();
    assert_eq!(sample.key_expr().as_str(), "stereosplat/diagnostics");
    assert!(sample.attachment().is_none());
    assert_eq!(sample.payload().to_bytes().as_ref(), &[7]);
    assert!(live_tokens(&b).await.is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_bad_node_name_is_a_typed_error() {
    let session = open(&TransportConfig::default()).await.unwrap();
    let keys = Keys::with_mode("stereosplat", KeyMode::Ros2 { domain_id: 0 });
    for name in ["", "9lives", "a/b", "a*b"] {
        let err = Outlet::declare(&session, &keys, name, &PUBLISHES, &[])
            .await
            .err()
            .expect("rejected");
        assert!(
            matches!(err, OutletError::NodeName(ref n) if n == name),
            "{err}"
        );
    }
}
