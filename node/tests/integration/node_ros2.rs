//! The node in ROS 2 key mode end to end, on real zenoh over loopback: a drive replayed on
//! rmw_zenoh keys (with attachments) comes out as bin maps on rmw_zenoh keys, each sample
//! carrying the 33-byte attachment with per-publisher sequence numbers 1, 2, 3, ..., and the
//! node is in the ROS graph: liveliness tokens for the node, each output it publishes and
//! each input it subscribes to, with the topic names, type hashes and QoS a ROS 2 node
//! expects (`/tf_static` transient local, keep last 1, as tf2's static broadcaster).
//! (No ROS 2 installation here: the formats are checked against rmw_zenoh's sources in
//! `transport::ros2`'s own tests.)

use crate::drive_support;

use drive_support::{Drive, RunningNode};
use model::synth::SynthConfig;
use node::bag::Rate;
use node::clients::replay;
use node::msg::gaussians::gaussians_from_cloud;
use node::msg::sensor_msgs::PointCloud2;
use node::msg::{Message, MessageKind};
use node::pipeline::worker::RenderWith;
use node::service::NodeConfig;
use node::transport::keys::{Direction, KeyMode, TOPICS};
use node::transport::open;
use node::transport::ros2::{qos_string, Attachment, EntityKind, Token};
use node::transport::Keys;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn in_ros2_mode_the_node_speaks_rmw_zenoh() {
    let drive = Drive::generate(
        "ros2",
        &SynthConfig {
            seed: 4,
            frames: 30,
            width: 136,
            height: 40,
            ..SynthConfig::default()
        },
    );
    let keys = Keys::with_mode("robot_ns", KeyMode::Ros2 { domain_id: 42 });
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        renders: RenderWith::Off,
        queue_capacity: 16,
        name: "mapper".into(),
        ..NodeConfig::default()
    })
    .await;
    let listener = open(&node.client()).await.unwrap();
    let maps = listener.declare_subscriber(keys.bin_map()).await.unwrap();

    // The ROS graph: the node, its publishers and its subscriptions.
    let tokens: Vec<Token> = {
        let replies = listener.liveliness().get("@ros2_lv/42/**").await.unwrap();
        let mut tokens = Vec::new();
        while let Ok(reply) = replies.recv_async().await {
            let sample = reply.result().expect("a token");
            tokens.push(Token::parse(sample.key_expr().as_str()).unwrap());
        }
        tokens
    };
    let nodes: Vec<_> = tokens
        .iter()
        .filter(|t| t.kind == EntityKind::Node)
        .collect();
    assert_eq!(nodes.len(), 1, "{tokens:?}");
    assert_eq!(
        (
            nodes[0].node.name.as_str(),
            nodes[0].node.namespace.as_str()
        ),
        ("mapper", "/robot_ns")
    );
    for t in TOPICS {
        let kind = match t.direction {
            Direction::Input => EntityKind::Subscription,
            Direction::Output => EntityKind::Publisher,
        };
        // Namespaced topics under /robot_ns; /tf and /tf_static absolute.
        let name = format!("/{}", keys.topic_name(t));
        let found = tokens
            .iter()
            .filter(|tok| tok.node.name == "mapper" && tok.kind == kind)
            .filter_map(|tok| tok.topic.as_ref())
            .find(|topic| topic.name == name)
            .unwrap_or_else(|| panic!("no {kind:?} token for {name}"));
        assert_eq!(found.type_name, t.kind.dds_type_name());
        assert_eq!(found.type_hash, t.kind.type_hash());
        assert_eq!(found.qos, qos_string(&t.qos), "{name}");
    }

    let player = open(&node.client()).await.unwrap();
    let left = keys.key(node::transport::keys::LEFT_IMAGE);
    assert!(drive_support::net_support::sees_a_subscriber(&player, &left).await);
    let replayed = replay(
        &player,
        &keys,
        &drive.sequence,
        Rate::Factor(4.0),
        &mut |_, _| {},
    )
    .await
    .unwrap();
    assert_eq!(replayed.frames, 30);
    let expected = drive.bins_opened(8.0) as u64;
    let mut sequences = Vec::new();
    let mut gid = None;
    while (sequences.len() as u64) < expected {
        let sample = tokio::time::timeout(std::time::Duration::from_secs(60), maps.recv_async())
            .await
            .expect("every bin map arrives")
            .unwrap();
        assert!(sample.key_expr().as_str().starts_with(&format!(
            "42/robot_ns/bin/map/{}/RIHS01_",
            MessageKind::PointCloud2.dds_type_name()
        )));
        let bytes = sample
            .attachment()
            .expect("an rmw_zenoh attachment")
            .to_bytes();
        let a = Attachment::decode(&bytes).unwrap();
        assert_eq!(*gid.get_or_insert(a.gid), a.gid, "one publisher, one GID");
        sequences.push(a.sequence);
        let cloud = PointCloud2::decode(&sample.payload().to_bytes()).unwrap();
        assert!(
            gaussians_from_cloud(&cloud, glam::DVec3::ZERO)
                .unwrap()
                .len()
                > 500
        );
    }
    assert_eq!(sequences, (1..=expected as i64).collect::<Vec<_>>());
    let summary = node.stop().await;
    assert_eq!(summary.bins_published, expected);
    assert_eq!(summary.counters.sum("bad_message/"), 0);
}
