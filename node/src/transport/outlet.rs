//! [`Outlet`]: how the node (and replay) publish, in either key mode.
//!
//! In plain mode it is a zenoh publisher per topic on `<namespace>/<topic>`, nothing more. In
//! ROS 2 mode it does what rmw_zenoh does for a node with publishers and subscriptions
//! (`rmw_zenoh_cpp/src/detail/rmw_node_data.cpp`, `rmw_publisher_data.cpp`), so ROS 2 nodes
//! on rmw_zenoh see the node, its topics and their types ([`super::ros2`]):
//!
//! - one liveliness token for the node (`NN`), one per published topic (`MP`) and one per
//!   subscribed topic (`MS`), alive as long as the outlet is;
//! - a zenoh publisher per published topic on rmw_zenoh's data key, reliable with congestion
//!   control *block*: a slow subscriber slows the publisher rather than losing maps (rmw_zenoh
//!   drops for keep-last publishers; the node's outputs are its product, so nothing it
//!   counts as published may vanish on the way);
//! - every sample with rmw_zenoh's 33-byte attachment: the publisher's sequence number from 1,
//!   the source timestamp (ns since the Unix epoch) and the publisher's GID.
//!
//! The ROS node lives in the namespace `/<namespace>`; its topics are `/<namespace>/<topic>`.
//! Node and entity ids come from one process-wide counter, as rmw_zenoh takes them from one
//! counter per session, so two outlets on one session never announce the same GID.

use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::Session;

use super::ros2::{self, Attachment, NodeInfo, TopicInfo, GID_LEN};
use crate::transport::keys::{KeyMode, Keys, Topic};

/// Why an outlet could not be declared or could not publish.
#[derive(Debug, thiserror::Error)]
pub enum OutletError {
    /// The node name is not a valid ROS 2 node name (it goes into liveliness keys).
    #[error(
        "{0:?} is not a ROS 2 node name (ASCII letters, digits and _, not starting with a digit)"
    )]
    NodeName(String),
    /// `put` on a topic the outlet was not declared to publish.
    #[error("topic {0} was not declared on this outlet")]
    NotDeclared(&'static str),
    /// zenoh refused a declaration or a put.
    #[error("zenoh: {0}")]
    Zenoh(String),
}

fn zenoh_err(e: zenoh::Error) -> OutletError {
    OutletError::Zenoh(e.to_string())
}

/// The next node or entity id (rmw_zenoh counts them per session; per process is stricter).
static NEXT_ENTITY_ID: AtomicU64 = AtomicU64::new(0);

fn next_entity_id() -> u64 {
    NEXT_ENTITY_ID.fetch_add(1, Ordering::Relaxed)
}

/// One published topic: its zenoh publisher and, in ROS 2 mode, its GID and sample counter.
struct Outgoing {
    topic: Topic,
    publisher: Publisher<'static>,
    /// `Some` in ROS 2 mode: samples then carry an attachment.
    gid: Option<[u8; GID_LEN]>,
    /// The sequence number of the next sample.
    next_sequence: AtomicI64,
}

/// The node's publishing side: zenoh publishers for its topics and, in ROS 2 mode, the
/// liveliness tokens that put it in the ROS graph. Dropping it withdraws both.
pub struct Outlet {
    outgoing: Vec<Outgoing>,
    token_keys: Vec<String>,
    /// Held for their lifetime: dropping a token undeclares it.
    _tokens: Vec<LivelinessToken>,
}

impl Outlet {
    /// Declares publishers for `publishes` (a topic listed twice counts once) and, in ROS 2
    /// mode, the node's liveliness token and one per topic in `publishes` and `subscribes`
    /// (the subscriptions themselves are the caller's; this only announces them).
    pub async fn declare(
        session: &Session,
        keys: &Keys,
        node_name: &str,
        publishes: &[Topic],
        subscribes: &[Topic],
    ) -> Result<Outlet, OutletError> {
        if !ros2::is_valid_node_name(node_name) {
            return Err(OutletError::NodeName(node_name.into()));
        }
        let mut unique: Vec<Topic> = Vec::new();
        for &t in publishes {
            if !unique.contains(&t) {
                unique.push(t);
            }
        }
        let node = match keys.mode {
            KeyMode::Plain => None,
            KeyMode::Ros2 { domain_id } => Some(NodeInfo {
                domain_id,
                zid: session.zid().to_string(),
                node_id: next_entity_id(),
                enclave: "/".into(),
                namespace: format!("/{}", keys.namespace),
                name: node_name.into(),
            }),
        };
        let mut token_keys = Vec::new();
        let mut outgoing = Vec::new();
        if let Some(node) = &node {
            token_keys.push(ros2::node_token(node));
        }
        for topic in unique {
            let publisher = session
                .declare_publisher(keys.key(topic))
                .congestion_control(CongestionControl::Block)
                .await
                .map_err(zenoh_err)?;
            let gid = node.as_ref().map(|node| {
                let key = ros2::publisher_token(node, next_entity_id(), &topic_info(keys, topic));
                let gid = ros2::gid(&key);
                token_keys.push(key);
                gid
            });
            outgoing.push(Outgoing {
                topic,
                publisher,
                gid,
                next_sequence: AtomicI64::new(1),
            });
        }
        if let Some(node) = &node {
            for &topic in subscribes {
                let info = topic_info(keys, topic);
                token_keys.push(ros2::subscription_token(node, next_entity_id(), &info));
            }
        }
        let mut tokens = Vec::with_capacity(token_keys.len());
        for key in &token_keys {
            let token = session
                .liveliness()
                .declare_token(key.clone())
                .await
                .map_err(zenoh_err)?;
            tokens.push(token);
        }
        Ok(Outlet {
            outgoing,
            token_keys,
            _tokens: tokens,
        })
    }

    /// Publishes `payload` (a CDR message) on `topic`'s key; in ROS 2 mode with rmw_zenoh's
    /// attachment (next sequence number, now, the publisher's GID).
    pub async fn put(&self, topic: Topic, payload: Vec<u8>) -> Result<(), OutletError> {
        let out = self
            .outgoing
            .iter()
            .find(|o| o.topic == topic)
            .ok_or(OutletError::NotDeclared(topic.name))?;
        let put = out.publisher.put(payload);
        let put = match out.gid {
            Some(gid) => put.attachment(
                Attachment {
                    sequence: out.next_sequence.fetch_add(1, Ordering::Relaxed),
                    source_timestamp_ns: now_ns(),
                    gid,
                }
                .encode()
                .to_vec(),
            ),
            None => put,
        };
        put.await.map_err(zenoh_err)
    }

    /// The GID of `topic`'s publisher (ROS 2 mode; `None` in plain mode or for a topic not
    /// declared).
    pub fn gid(&self, topic: Topic) -> Option<[u8; GID_LEN]> {
        self.outgoing.iter().find(|o| o.topic == topic)?.gid
    }

    /// The key expressions of the liveliness tokens held (node first, then publishers, then
    /// subscriptions; empty in plain mode), for logs.
    pub fn token_keys(&self) -> &[String] {
        &self.token_keys
    }
}

/// What a token says about `topic`: its fully qualified name, DDS type, type hash, QoS.
fn topic_info(keys: &Keys, topic: Topic) -> TopicInfo {
    TopicInfo {
        name: format!("/{}", keys.topic_name(topic)),
        type_name: topic.kind.dds_type_name(),
        type_hash: topic.kind.type_hash().to_string(),
        qos: ros2::qos_string(&topic.qos),
    }
}

/// Now in ns since the Unix epoch (rmw_zenoh's `get_system_time_in_ns`); 0 before the epoch.
fn now_ns() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}
