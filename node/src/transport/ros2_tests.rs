//! Unit tests of [`super`] against literal values: the example tokens of rmw_zenoh's
//! design page (its `docs/design.md`, "Graph Cache", demo_nodes_cpp talker and listener)
//! and XXH3-128 values computed with the reference xxHash C library (libxxhash 0.8.1,
//! `XXH3_128bits`, through Python's ctypes), laid out low 64 bits then high 64 bits, little
//! endian, as rmw_zenoh's `liveliness_utils.cpp` copies them.

use super::*;

const CHATTER_HASH: &str =
    "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";

fn demo_node(zid: &str, name: &str) -> NodeInfo {
    NodeInfo {
        domain_id: 2,
        zid: zid.into(),
        node_id: 0,
        enclave: "/".into(),
        namespace: "/".into(),
        name: name.into(),
    }
}

fn chatter(depth: u32) -> TopicInfo {
    TopicInfo {
        name: "/chatter".into(),
        type_name: "std_msgs::msg::dds_::String_".into(),
        type_hash: CHATTER_HASH.into(),
        qos: qos_string(&Qos {
            history: History::KeepLast(depth),
            ..Qos::NODE
        }),
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn attachment_layout_is_seq_stamp_len_gid() {
    let gid: [u8; 16] = std::array::from_fn(|i| 0xa0 + i as u8);
    let a = Attachment {
        sequence: 0x0102_0304_0506_0708,
        source_timestamp_ns: -2,
        gid,
    };
    let bytes = a.encode();
    assert_eq!(bytes.len(), 33);
    assert_eq!(&bytes[..8], &[8, 7, 6, 5, 4, 3, 2, 1]);
    assert_eq!(
        &bytes[8..16],
        &[0xfe, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff]
    );
    assert_eq!(bytes[16], 16);
    assert_eq!(&bytes[17..], &gid);
    assert_eq!(Attachment::decode(&bytes), Ok(a));
}

#[test]
fn bad_attachments_are_typed_errors() {
    let good = Attachment {
        sequence: 1,
        source_timestamp_ns: 2,
        gid: [3; 16],
    }
    .encode();
    for len in [0, 1, 16, 17, 32, 34, 100] {
        let mut bytes = good.to_vec();
        bytes.resize(len, 0);
        assert_eq!(
            Attachment::decode(&bytes),
            Err(AttachmentError::Length(len))
        );
    }
    let mut bytes = good;
    bytes[16] = 15;
    assert_eq!(
        Attachment::decode(&bytes),
        Err(AttachmentError::GidLength(15))
    );
}

#[test]
fn gid_is_xxh3_128_low_then_high_little_endian() {
    let cases = [
        ("", "7f498d4624c30160d8984701d306aa99"),
        ("abc", "50392f89945faf7885613a73b65ab006"),
        (&"a".repeat(16), "158d82c4dd505724d030680654509fff"),
        (&"b".repeat(100), "3a2c816c0c5fb2fa4872b64bdd070498"),
        (&"c".repeat(240), "311ba725114969980f659e34b799537f"),
        (&"d".repeat(300), "475059f7471ae44411b7d9c396a6a61f"),
    ];
    for (input, expected) in cases {
        assert_eq!(hex(&gid(input)), expected, "input of {} bytes", input.len());
    }
}

#[test]
fn qos_strings_leave_rmw_zenoh_defaults_empty() {
    // rmw_zenoh's `docs/design.md`: the listener's subscription (rclcpp default, depth 10)
    // and the talker's publisher (depth 7).
    assert_eq!(qos_string(&Qos::NODE), "::,10:,:,:,,");
    let depth7 = Qos {
        history: History::KeepLast(7),
        ..Qos::NODE
    };
    assert_eq!(qos_string(&depth7), "::,7:,:,:,,");
    // rmw_zenoh's own default (qos.cpp): everything empty.
    let default = Qos {
        history: History::KeepLast(42),
        ..Qos::NODE
    };
    assert_eq!(qos_string(&default), "::,:,:,:,,");
    let other = Qos {
        reliability: Reliability::BestEffort,
        durability: Durability::TransientLocal,
        history: History::KeepAll,
    };
    assert_eq!(qos_string(&other), "2:1:2,:,:,:,,");
}

#[test]
fn tokens_match_the_design_doc_examples() {
    let listener = demo_node("aac3178e146ba6f1fc6e6a4085e77f21", "listener");
    let talker = demo_node("8b20917502ee955ac4476e0266340d5c", "talker");
    let nn = node_token(&listener);
    assert_eq!(
        nn,
        "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    );
    let ms = subscription_token(&listener, 10, &chatter(10));
    assert_eq!(
        ms,
        format!(
            "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/\
             std_msgs::msg::dds_::String_/{CHATTER_HASH}/::,10:,:,:,,"
        )
    );
    let mp = publisher_token(&talker, 10, &chatter(7));
    assert_eq!(
        mp,
        format!(
            "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/\
             std_msgs::msg::dds_::String_/{CHATTER_HASH}/::,7:,:,:,,"
        )
    );
    // The GIDs rmw_zenoh would give these entities (reference XXH3-128 of the keys).
    assert_eq!(hex(&gid(&nn)), "49877999dacb858702d11ac823785912");
    assert_eq!(hex(&gid(&ms)), "76148a538308fe55a6c5375462ca1de6");
    assert_eq!(hex(&gid(&mp)), "ac170f31eadcd9ff0cd86d7a17907d1c");
}

#[test]
fn namespaces_and_topics_are_mangled_and_parse_back() {
    let node = NodeInfo {
        domain_id: 0,
        zid: "1f".into(),
        node_id: 3,
        enclave: "/".into(),
        namespace: "/robot/ss".into(),
        name: "stereosplat_node".into(),
    };
    let topic = TopicInfo {
        name: "/robot/ss/left/image".into(),
        type_name: "sensor_msgs::msg::dds_::Image_".into(),
        type_hash: "RIHS01_00".into(),
        qos: qos_string(&Qos::NODE),
    };
    let key = publisher_token(&node, 4, &topic);
    assert_eq!(
        key,
        "@ros2_lv/0/1f/3/4/MP/%/%robot%ss/stereosplat_node/%robot%ss%left%image/\
         sensor_msgs::msg::dds_::Image_/RIHS01_00/::,10:,:,:,,"
    );
    let parsed = Token::parse(&key).unwrap();
    assert_eq!(parsed.kind, EntityKind::Publisher);
    assert_eq!(parsed.entity_id, 4);
    assert_eq!(parsed.node, node);
    assert_eq!(parsed.topic.as_ref(), Some(&topic));
    assert_eq!(parsed.to_string(), key);
    assert_eq!(parsed.gid(), gid(&key));
    let nn = Token::parse(&node_token(&node)).unwrap();
    assert_eq!(
        (nn.kind, nn.entity_id, nn.topic),
        (EntityKind::Node, 3, None)
    );
}

#[test]
fn malformed_tokens_are_typed_errors() {
    let key = "@ros2_lv/0/1f/3/3/NN/%/%/n";
    assert!(Token::parse(key).is_ok());
    assert!(matches!(
        Token::parse("0/1f/3/3/NN/%/%/n"),
        Err(TokenError::AdminSpace(_))
    ));
    assert!(matches!(
        Token::parse("@ros2_lv/0/1f/3/3/NN/%/%"),
        Err(TokenError::Shape { parts: 8, .. })
    ));
    assert!(matches!(
        Token::parse("@ros2_lv/0/1f/3/3/MP/%/%/n"),
        Err(TokenError::Shape {
            parts: 9,
            expected: 13,
            ..
        })
    ));
    assert!(matches!(
        Token::parse("@ros2_lv/0/1f/3/3/XX/%/%/n/t/ty/h/q"),
        Err(TokenError::Kind { .. })
    ));
    assert!(matches!(
        Token::parse("@ros2_lv/x/1f/3/3/NN/%/%/n"),
        Err(TokenError::Number {
            field: "domain id",
            ..
        })
    ));
    assert!(matches!(
        Token::parse("@ros2_lv/0/1f/3//NN/%/%/n"),
        Err(TokenError::Shape { .. })
    ));
    assert!(Token::parse("").is_err());
}

#[test]
fn node_names_follow_ros_rules() {
    for ok in ["stereosplat_node", "_n", "a1"] {
        assert!(is_valid_node_name(ok), "{ok}");
    }
    for bad in ["", "1a", "a/b", "a-b", "a*", "nœud"] {
        assert!(!is_valid_node_name(bad), "{bad}");
    }
}
