//! rmw_zenoh's wire conventions, so ROS 2 nodes running on rmw_zenoh (Jazzy) see the node's
//! topics and the node in their graph. Pure functions and types; [`super::outlet`] uses them.
//!
//! Everything here was read from `ros2/rmw_zenoh` (files under `rmw_zenoh_cpp/src/detail/`
//! and rmw_zenoh's `docs/design.md`), written anew:
//!
//! - **Attachment** (`attachment_helpers.cpp`, `rmw_publisher_data.cpp`): every sample carries
//!   three values written with zenoh-ext's serializer: the sequence number (int64, little
//!   endian), the source timestamp in ns since the Unix epoch (int64, little endian), and the
//!   16-byte GID as a `std::array<uint8_t, 16>`, i.e. a sequence: its length as a LEB128 varint
//!   (one byte, 16) then the bytes. 8 + 8 + 1 + 16 = 33 bytes. The publisher's sequence number
//!   starts at 1 and grows by one per sample.
//! - **GID** (`liveliness_utils.cpp`, `Entity::Entity`): the XXH3 128-bit hash of the
//!   entity's liveliness key expression, its low 64 bits then its high 64 bits, each in the
//!   machine's (little-endian) byte order. Derived, not random: the same key gives the same GID.
//! - **Liveliness tokens** (`liveliness_utils.cpp`, its `docs/design.md` "Graph Cache"):
//!   `@ros2_lv/<domain>/<session zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node
//!   name>`, and for topics `/<topic>/<dds type>/<type hash>/<qos>` after it. A node's entity id
//!   is its node id. Names are mangled: every `/` becomes `%` (so the default enclave and an
//!   empty namespace, both `/`, are written `%`, and `/ns/topic` is `%ns%topic`). Kinds: `NN`
//!   node, `MP` publisher, `MS` subscription, `SS` service, `SC` client.
//! - **QoS** (`liveliness_utils.cpp` `qos_to_keyexpr`, `qos.cpp`): `rel:dur:hist,depth:
//!   deadline_s,deadline_ns:lifespan_s,lifespan_ns:liveliness,lease_s,lease_ns`, where a field
//!   equal to rmw_zenoh's default is left empty. The defaults are reliable, volatile, keep last
//!   42, infinite deadline and lifespan, automatic liveliness with an infinite lease; the
//!   numbers are the `rmw_qos_*_policy_t` enum values of `rmw/types.h`.

use std::fmt;

/// The key prefix of every rmw_zenoh liveliness token (a hermetic zenoh namespace: `**`
/// elsewhere never matches it).
pub const ADMIN_SPACE: &str = "@ros2_lv";
/// Bytes in a GID (`RMW_GID_STORAGE_SIZE`).
pub const GID_LEN: usize = 16;
/// Bytes in rmw_zenoh's sample attachment.
pub const ATTACHMENT_LEN: usize = 8 + 8 + 1 + GID_LEN;

/// The metadata rmw_zenoh puts on every published sample, which a ROS 2 subscriber reads to
/// fill `rmw_message_info_t` (and rejects the sample without).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Attachment {
    /// The publisher's sample counter, 1 for its first sample.
    pub sequence: i64,
    /// When the sample was published, ns since the Unix epoch.
    pub source_timestamp_ns: i64,
    /// The publisher's GID ([`gid`]).
    pub gid: [u8; GID_LEN],
}

/// Why bytes are not an rmw_zenoh attachment.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AttachmentError {
    /// Not 33 bytes long.
    #[error("an rmw_zenoh attachment is {ATTACHMENT_LEN} bytes, this one is {0}")]
    Length(usize),
    /// The GID's length prefix is not 16.
    #[error("the attachment's GID length prefix is {0}, not {GID_LEN}")]
    GidLength(u8),
}

impl Attachment {
    /// The 33 bytes rmw_zenoh writes: sequence and timestamp as int64 LE, then the GID as a
    /// length-prefixed sequence (prefix 16).
    pub fn encode(&self) -> [u8; ATTACHMENT_LEN] {
        let mut out = [0u8; ATTACHMENT_LEN];
        out[..8].copy_from_slice(&self.sequence.to_le_bytes());
        out[8..16].copy_from_slice(&self.source_timestamp_ns.to_le_bytes());
        out[16] = GID_LEN as u8;
        out[17..].copy_from_slice(&self.gid);
        out
    }

    /// Reads what [`Attachment::encode`] (or rmw_zenoh) wrote; never panics.
    pub fn decode(bytes: &[u8]) -> Result<Self, AttachmentError> {
        let bytes: &[u8; ATTACHMENT_LEN] = bytes
            .try_into()
            .map_err(|_| AttachmentError::Length(bytes.len()))?;
        if bytes[16] != GID_LEN as u8 {
            return Err(AttachmentError::GidLength(bytes[16]));
        }
        let word = |at: usize| {
            let mut w = [0u8; 8];
            w.copy_from_slice(&bytes[at..at + 8]);
            i64::from_le_bytes(w)
        };
        let mut gid = [0u8; GID_LEN];
        gid.copy_from_slice(&bytes[17..]);
        Ok(Self {
            sequence: word(0),
            source_timestamp_ns: word(8),
            gid,
        })
    }
}

/// The GID rmw_zenoh gives the entity whose liveliness key expression is `token`: XXH3-128 of
/// the key's bytes, low 64 bits then high 64 bits, little endian.
pub fn gid(token: &str) -> [u8; GID_LEN] {
    let hash = xxhash_rust::xxh3::xxh3_128(token.as_bytes());
    let mut out = [0u8; GID_LEN];
    out[..8].copy_from_slice(&(hash as u64).to_le_bytes());
    out[8..].copy_from_slice(&((hash >> 64) as u64).to_le_bytes());
    out
}

/// rmw_zenoh's name mangling for liveliness keys: every `/` becomes `%`.
pub fn mangle(name: &str) -> String {
    name.replace('/', "%")
}

/// The inverse of [`mangle`].
pub fn demangle(name: &str) -> String {
    name.replace('%', "/")
}

/// A QoS reliability policy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reliability {
    /// Delivery is retried (`RMW_QOS_POLICY_RELIABILITY_RELIABLE`, 1; rmw_zenoh's default).
    Reliable,
    /// Samples may be dropped (`RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT`, 2).
    BestEffort,
}

/// A QoS durability policy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Durability {
    /// Late joiners get nothing old (`RMW_QOS_POLICY_DURABILITY_VOLATILE`, 2; the default).
    Volatile,
    /// Late joiners get the last samples (`RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL`, 1).
    TransientLocal,
}

/// A QoS history policy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum History {
    /// Keep the last N samples (`RMW_QOS_POLICY_HISTORY_KEEP_LAST`, 1; default depth 42).
    KeepLast(u32),
    /// Keep everything (`RMW_QOS_POLICY_HISTORY_KEEP_ALL`, 2).
    KeepAll,
}

/// The QoS policies a token announces (deadline, lifespan and liveliness are always
/// rmw_zenoh's defaults here: infinite, infinite, automatic).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qos {
    /// Reliability.
    pub reliability: Reliability,
    /// Durability.
    pub durability: Durability,
    /// History and depth.
    pub history: History,
}

impl Qos {
    /// What the node publishes and subscribes with: rclcpp's default profile (reliable,
    /// volatile, keep last 10), so `ros2 topic echo` with its defaults matches it.
    pub const NODE: Qos = Qos {
        reliability: Reliability::Reliable,
        durability: Durability::Volatile,
        history: History::KeepLast(10),
    };
}

/// `qos` in rmw_zenoh's compact token form, fields equal to rmw_zenoh's default left empty:
/// [`Qos::NODE`] is `::,10:,:,:,,`.
pub fn qos_string(qos: &Qos) -> String {
    let reliability = match qos.reliability {
        Reliability::Reliable => "",
        Reliability::BestEffort => "2",
    };
    let durability = match qos.durability {
        Durability::Volatile => "",
        Durability::TransientLocal => "1",
    };
    let (history, depth) = match qos.history {
        History::KeepLast(42) => ("", String::new()),
        History::KeepLast(depth) => ("", depth.to_string()),
        History::KeepAll => ("2", String::new()),
    };
    format!("{reliability}:{durability}:{history},{depth}:,:,:,,")
}

/// What kind of ROS 2 entity a token announces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EntityKind {
    /// A node (`NN`).
    Node,
    /// A message publisher (`MP`).
    Publisher,
    /// A message subscription (`MS`).
    Subscription,
    /// A service server (`SS`).
    Service,
    /// A service client (`SC`).
    Client,
}

impl EntityKind {
    /// The two-letter code in the token.
    pub fn code(self) -> &'static str {
        match self {
            Self::Node => "NN",
            Self::Publisher => "MP",
            Self::Subscription => "MS",
            Self::Service => "SS",
            Self::Client => "SC",
        }
    }

    /// The kind a two-letter code stands for.
    pub fn from_code(code: &str) -> Option<Self> {
        [
            Self::Node,
            Self::Publisher,
            Self::Subscription,
            Self::Service,
            Self::Client,
        ]
        .into_iter()
        .find(|k| k.code() == code)
    }
}

/// The node an entity belongs to, as every token of it says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeInfo {
    /// `ROS_DOMAIN_ID`.
    pub domain_id: u32,
    /// The zenoh session id, as zenoh prints it (lowercase hex).
    pub zid: String,
    /// The node's id within the session (rmw_zenoh counts entities per session).
    pub node_id: u64,
    /// The SROS enclave, `/` when unset.
    pub enclave: String,
    /// The node's namespace with its leading slash, `/` when empty.
    pub namespace: String,
    /// The node's name.
    pub name: String,
}

/// The topic of a publisher or subscription token.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TopicInfo {
    /// The fully qualified topic name, with its leading slash.
    pub name: String,
    /// The DDS type name, e.g. `std_msgs::msg::dds_::String_`.
    pub type_name: String,
    /// The RIHS01 type hash, `RIHS01_<64 hex digits>`.
    pub type_hash: String,
    /// The QoS in [`qos_string`] form (kept as text when parsed).
    pub qos: String,
}

/// One liveliness token: which entity of which node, and its topic for publishers and
/// subscriptions.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Token {
    /// The node.
    pub node: NodeInfo,
    /// The entity's id within the session (the node id for a node token).
    pub entity_id: u64,
    /// Node, publisher, subscription, ...
    pub kind: EntityKind,
    /// The topic; `None` for a node.
    pub topic: Option<TopicInfo>,
}

/// Why a key expression is not an rmw_zenoh liveliness token.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TokenError {
    /// It does not start with `@ros2_lv/`.
    #[error("{0}: not under {ADMIN_SPACE}")]
    AdminSpace(String),
    /// Too few or too many `/`-separated parts, or an empty one.
    #[error("{key}: {parts} parts, a {kind} token has {expected}")]
    Shape {
        /// The key.
        key: String,
        /// The kind code read (or `?`).
        kind: String,
        /// Its number of parts.
        parts: usize,
        /// The number a token of that kind has.
        expected: usize,
    },
    /// An unknown entity kind code.
    #[error("{key}: unknown entity kind {code:?}")]
    Kind {
        /// The key.
        key: String,
        /// The code read.
        code: String,
    },
    /// The domain, node id or entity id is not a number.
    #[error("{key}: the {field} is not a number")]
    Number {
        /// The key.
        key: String,
        /// Which field.
        field: &'static str,
    },
}

/// Parts of a node token: `@ros2_lv/domain/zid/nid/id/kind/enclave/ns/name`.
const NODE_PARTS: usize = 9;
/// Parts of a topic token: the node's plus `topic/type/hash/qos`.
const TOPIC_PARTS: usize = NODE_PARTS + 4;

impl Token {
    /// The token's key expression.
    pub fn key_expr(&self) -> String {
        let n = &self.node;
        let mut key = format!(
            "{ADMIN_SPACE}/{}/{}/{}/{}/{}/{}/{}/{}",
            n.domain_id,
            n.zid,
            n.node_id,
            self.entity_id,
            self.kind.code(),
            mangle(&n.enclave),
            mangle(&n.namespace),
            mangle(&n.name)
        );
        if let Some(t) = &self.topic {
            key += &format!(
                "/{}/{}/{}/{}",
                mangle(&t.name),
                mangle(&t.type_name),
                mangle(&t.type_hash),
                t.qos
            );
        }
        key
    }

    /// The entity's GID, the hash of [`Token::key_expr`].
    pub fn gid(&self) -> [u8; GID_LEN] {
        gid(&self.key_expr())
    }

    /// Reads a token's key expression back (as rmw_zenoh's graph cache does).
    pub fn parse(key: &str) -> Result<Self, TokenError> {
        let parts: Vec<&str> = key.split('/').collect();
        if parts[0] != ADMIN_SPACE {
            return Err(TokenError::AdminSpace(key.into()));
        }
        let code = parts.get(5).copied().unwrap_or("?");
        let kind = EntityKind::from_code(code);
        let expected = match kind {
            Some(EntityKind::Node) => NODE_PARTS,
            _ => TOPIC_PARTS,
        };
        if parts.len() != expected || parts.iter().any(|p| p.is_empty()) {
            return Err(TokenError::Shape {
                key: key.into(),
                kind: code.into(),
                parts: parts.len(),
                expected,
            });
        }
        let kind = kind.ok_or_else(|| TokenError::Kind {
            key: key.into(),
            code: code.into(),
        })?;
        let number = |i: usize, field| {
            parts[i].parse::<u64>().map_err(|_| TokenError::Number {
                key: key.into(),
                field,
            })
        };
        let domain_id = u32::try_from(number(1, "domain id")?).map_err(|_| TokenError::Number {
            key: key.into(),
            field: "domain id",
        })?;
        Ok(Self {
            node: NodeInfo {
                domain_id,
                zid: parts[2].into(),
                node_id: number(3, "node id")?,
                enclave: demangle(parts[6]),
                namespace: demangle(parts[7]),
                name: demangle(parts[8]),
            },
            entity_id: number(4, "entity id")?,
            kind,
            topic: (kind != EntityKind::Node).then(|| TopicInfo {
                name: demangle(parts[9]),
                type_name: demangle(parts[10]),
                type_hash: demangle(parts[11]),
                qos: parts[12].into(),
            }),
        })
    }
}

impl fmt::Display for Token {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.key_expr())
    }
}

/// The key expression of `node`'s own token (`NN`; its entity id is its node id).
pub fn node_token(node: &NodeInfo) -> String {
    Token {
        node: node.clone(),
        entity_id: node.node_id,
        kind: EntityKind::Node,
        topic: None,
    }
    .key_expr()
}

/// The key expression of a publisher token (`MP`) of `node` on `topic`.
pub fn publisher_token(node: &NodeInfo, entity_id: u64, topic: &TopicInfo) -> String {
    topic_token(node, entity_id, EntityKind::Publisher, topic)
}

/// The key expression of a subscription token (`MS`) of `node` on `topic`.
pub fn subscription_token(node: &NodeInfo, entity_id: u64, topic: &TopicInfo) -> String {
    topic_token(node, entity_id, EntityKind::Subscription, topic)
}

fn topic_token(node: &NodeInfo, entity_id: u64, kind: EntityKind, topic: &TopicInfo) -> String {
    Token {
        node: node.clone(),
        entity_id,
        kind,
        topic: Some(topic.clone()),
    }
    .key_expr()
}

/// Whether `name` is a valid ROS 2 node name: ASCII letters, digits and `_`, not starting
/// with a digit, not empty (rmw_zenoh puts it into key expressions as is).
pub fn is_valid_node_name(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

#[cfg(test)]
#[path = "ros2_tests.rs"]
mod tests;
