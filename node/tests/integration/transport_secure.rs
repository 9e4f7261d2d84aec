//! The node's network exposure, on loopback only: with no endpoint it listens on loopback; a
//! non-loopback listen endpoint is warned about (checked from the configuration, nothing is
//! bound there); the secure profile (TLS with mutual authentication, certificates made here
//! with rcgen, plus the access control of `launch/zenoh_acl.json5`) keeps out a peer without
//! a client certificate and one whose certificate another authority signed, and lets a
//! viewer read but not publish inputs while the camera's inputs get through; a second node on
//! a port in use fails before it says it is ready; and only a worker process with its own
//! certificate takes the node's bins, on its own key (another worker's certificate, or a
//! viewer's, gets none).

use crate::drive_support::{wait_counted, Drive, Player};
use crate::net_support::{self, sees_a_subscriber};
use crate::node_workers::WorkerProcess;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use node::pipeline::worker::RenderWith;
use node::service::{NodeConfig, NodeSummary, ServiceError, WorkersConfig};
use node::transport::Keys;
use node::transport::{open, TlsFiles, TransportConfig, TransportError};
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use zenoh::Session;

const ACL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../launch/zenoh_acl.json5");

/// A certificate authority made for the test, writing PEM files into a folder.
struct Authority {
    dir: PathBuf,
    name: String,
    issuer: Issuer<'static, KeyPair>,
}

impl Authority {
    /// A fresh self-signed authority `name`; its certificate is written to `<name>.pem`.
    fn new(dir: &Path, name: &str) -> Self {
        let mut params = CertificateParams::new(Vec::<String>::new()).unwrap();
        params.distinguished_name.push(DnType::CommonName, name);
        params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
        params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
        let key = KeyPair::generate().unwrap();
        let cert = params.self_signed(&key).unwrap();
        std::fs::write(dir.join(format!("{name}.pem")), cert.pem()).unwrap();
        Self {
            dir: dir.to_path_buf(),
            name: name.into(),
            issuer: Issuer::new(params, key),
        }
    }

    /// The authority's certificate file.
    fn ca(&self) -> PathBuf {
        self.dir.join(format!("{}.pem", self.name))
    }

    /// A certificate with common name `cn` for 127.0.0.1 and localhost, signed by this
    /// authority and trusting `trust` (the authority peers are checked against).
    fn identity(&self, cn: &str, trust: &Path) -> TlsFiles {
        let mut params =
            CertificateParams::new(vec!["127.0.0.1".to_string(), "localhost".to_string()]).unwrap();
        params.distinguished_name.push(DnType::CommonName, cn);
        params.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        let key = KeyPair::generate().unwrap();
        let cert = params.signed_by(&key, &self.issuer).unwrap();
        let stem = format!("{}-{cn}", self.name);
        let files = TlsFiles {
            ca: trust.to_path_buf(),
            cert: self.dir.join(format!("{stem}.pem")),
            key: self.dir.join(format!("{stem}.key")),
        };
        std::fs::write(&files.cert, cert.pem()).unwrap();
        std::fs::write(&files.key, key.serialize_pem()).unwrap();
        files
    }
}

/// A fresh folder under the temp dir for this test.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereosplat-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Waits (at most 20 s, a guard against hangs) until `session` is connected to a peer.
async fn wait_connected(session: &Session) -> bool {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(20) {
        if session.info().peers_zid().await.next().is_some() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    false
}

/// Publishes `n` payloads that are not a valid message (the node counts each one it
/// receives as bad input) on the left image key, then closes the session so they are
/// flushed.
async fn publish_garbage(session: Session, keys: &Keys, n: usize) {
    let publisher = session.declare_publisher(keys.left_image()).await.unwrap();
    for _ in 0..n {
        publisher.put(vec![0xA5u8; 12]).await.unwrap();
    }
    drop(publisher);
    session.close().await.unwrap();
}

#[test]
fn with_no_endpoint_the_node_listens_on_loopback_only() {
    let config = TransportConfig::default().zenoh_config().unwrap();
    assert_eq!(
        node::transport::session::listen_endpoints(&config).unwrap(),
        ["tcp/127.0.0.1:0"]
    );
    assert!(TransportConfig::default()
        .exposure_warnings()
        .unwrap()
        .is_empty());

    // A config file that names no endpoint gets the loopback default too; one that names
    // some keeps them (and a non-loopback one is warned about).
    let dir = temp_dir("zenoh-default");
    let quiet = dir.join("quiet.json5");
    std::fs::write(&quiet, "{ scouting: { delay: 100 } }").unwrap();
    let lan = dir.join("lan.json5");
    std::fs::write(
        &lan,
        r#"{ listen: { endpoints: ["tcp/192.168.1.20:7447"] } }"#,
    )
    .unwrap();
    let from = |file: &Path| TransportConfig {
        config_file: Some(file.to_path_buf()),
        ..TransportConfig::default()
    };
    let quiet_config = from(&quiet).zenoh_config().unwrap();
    assert_eq!(
        node::transport::session::listen_endpoints(&quiet_config).unwrap(),
        ["tcp/127.0.0.1:0"]
    );
    let warnings = from(&lan).exposure_warnings().unwrap();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("tcp/192.168.1.20:7447"),
        "{warnings:?}"
    );

    // A router keeps zenoh's port, on loopback.
    let router = TransportConfig {
        mode: "router".into(),
        ..TransportConfig::default()
    };
    assert_eq!(
        node::transport::session::listen_endpoints(&router.zenoh_config().unwrap()).unwrap(),
        ["tcp/127.0.0.1:7447"]
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn listening_on_every_interface_is_warned_about_without_binding_it() {
    let listen = |endpoints: &[&str]| TransportConfig {
        listen: endpoints.iter().map(|e| e.to_string()).collect(),
        ..TransportConfig::default()
    };
    let warnings = listen(&["tcp/127.0.0.1:7447", "tcp/0.0.0.0:7447", "tcp/[::]:7448"])
        .exposure_warnings()
        .unwrap();
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(warnings[0].starts_with("warning: listening on tcp/0.0.0.0:7447, every network"));
    assert!(warnings[1].starts_with("warning: listening on tcp/[::]:7448, every network"));
    assert!(warnings.iter().all(|w| w.contains("without TLS")));
    assert!(listen(&["tcp/[::1]:7447", "tcp/localhost:7447"])
        .exposure_warnings()
        .unwrap()
        .is_empty());
}

#[test]
fn the_secure_profile_refuses_plain_endpoints() {
    let dir = temp_dir("zenoh-plain");
    let ca = Authority::new(&dir, "ca");
    let tls = ca.identity("stereosplat-node", &ca.ca());
    let config = TransportConfig {
        listen: vec!["tcp/127.0.0.1:7447".into()],
        tls: Some(tls.clone()),
        ..TransportConfig::default()
    };
    match config.zenoh_config() {
        Err(TransportError::Unencrypted { endpoint }) => assert_eq!(endpoint, "tcp/127.0.0.1:7447"),
        other => panic!("expected Unencrypted, got {other:?}"),
    }
    // With no endpoint the default listener is TLS on loopback.
    let default = TransportConfig {
        tls: Some(tls),
        ..TransportConfig::default()
    };
    assert_eq!(
        node::transport::session::listen_endpoints(&default.zenoh_config().unwrap()).unwrap(),
        ["tls/127.0.0.1:0"]
    );
    // A missing key file is named.
    let missing = TransportConfig {
        tls: Some(TlsFiles {
            key: dir.join("nowhere.key"),
            ..ca.identity("stereosplat-node", &ca.ca())
        }),
        ..TransportConfig::default()
    };
    let err = missing.zenoh_config().unwrap_err();
    assert!(err.to_string().contains("nowhere.key"), "{err}");
    let _ = std::fs::remove_dir_all(dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn mutual_tls_and_access_control_admit_only_the_allowed_peers() {
    let dir = temp_dir("zenoh-secure");
    let ca = Authority::new(&dir, "ca");
    let rogue = Authority::new(&dir, "rogue");
    let port = net_support::free_port();
    let endpoint = format!("tls/127.0.0.1:{port}");
    let keys = Keys::default();

    // The node, in the secure profile, as `run --listen tls/... --tls-* --acl` sets it up.
    let node_transport = TransportConfig {
        listen: vec![endpoint.clone()],
        tls: Some(ca.identity("stereosplat-node", &ca.ca())),
        access_control: Some(PathBuf::from(ACL)),
        ..TransportConfig::default()
    };
    let config = NodeConfig {
        transport: node_transport,
        method: "sgm".into(),
        ..NodeConfig::default()
    };
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let (ready_tx, ready_rx) = tokio::sync::oneshot::channel::<()>();
    let node: tokio::task::JoinHandle<Result<NodeSummary, ServiceError>> =
        tokio::spawn(node::service::run_announced(
            config,
            async {
                let _ = stop_rx.await;
            },
            move |_: &zenoh::Session| {
                let _ = ready_tx.send(());
            },
        ));
    tokio::time::timeout(Duration::from_secs(60), ready_rx)
        .await
        .expect("the node is ready within 60 s")
        .expect("the node starts");

    let peer = |tls: Option<TlsFiles>| TransportConfig {
        connect: vec![endpoint.clone()],
        tls,
        ..TransportConfig::default()
    };
    // A peer that trusts the authority but has no certificate of its own.
    let mut no_cert = peer(None).zenoh_config().unwrap();
    no_cert
        .insert_json5(
            "transport/link/tls/root_ca_certificate",
            &serde_json::to_string(&ca.ca()).unwrap(),
        )
        .unwrap();
    let no_cert = zenoh::open(no_cert).await.unwrap();
    // A peer whose certificate, with the camera's name, another authority signed.
    let forged = open(&peer(Some(rogue.identity("stereosplat-camera", &ca.ca()))))
        .await
        .unwrap();
    // A plain TCP peer on the TLS port.
    let plain = open(&TransportConfig {
        connect: vec![format!("tcp/127.0.0.1:{port}")],
        ..TransportConfig::default()
    })
    .await
    .unwrap();
    // The two allowed identities.
    let viewer = open(&peer(Some(ca.identity("stereosplat-viewer", &ca.ca()))))
        .await
        .unwrap();
    let camera = open(&peer(Some(ca.identity("stereosplat-camera", &ca.ca()))))
        .await
        .unwrap();
    assert!(wait_connected(&viewer).await, "the viewer connects");
    assert!(wait_connected(&camera).await, "the camera connects");

    // The node's input subscription reaches the camera (so the camera's inputs are sent).
    assert!(sees_a_subscriber(&camera, &keys.left_image()).await);

    // The viewer may query the map snapshot (asked until the node's queryable has reached
    // it); the camera, which has the node's declarations by now, may not.
    let replies = |session: &Session| {
        let (session, key) = (session.clone(), keys.snapshot_request());
        async move {
            let replies = session.get(key).await.unwrap();
            let mut n = 0;
            while let Ok(reply) = replies.recv_async().await {
                n += usize::from(reply.result().is_ok());
            }
            n
        }
    };
    let start = Instant::now();
    while replies(&viewer).await == 0 {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "the viewer gets the snapshot"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(replies(&camera).await, 0, "the camera gets no snapshot");

    // The viewer sees the node's input subscription, so what it publishes there is sent:
    // the node's access control has to drop it.
    assert!(sees_a_subscriber(&viewer, &keys.left_image()).await);

    // None of the refused peers ever got a session with the node.
    for (name, session) in [
        ("no certificate", &no_cert),
        ("forged", &forged),
        ("plain", &plain),
    ] {
        let peers = session.info().peers_zid().await.count();
        assert_eq!(peers, 0, "the {name} peer is connected");
    }

    // Everyone publishes a different number of bad messages: the node counts the camera's.
    // A second viewer session watches the counters (the first one's publishes and closes).
    let watcher = open(&peer(Some(ca.identity("stereosplat-viewer", &ca.ca()))))
        .await
        .unwrap();
    let diagnostics = watcher
        .declare_subscriber(keys.diagnostics())
        .await
        .unwrap();
    publish_garbage(viewer, &keys, 7).await;
    publish_garbage(no_cert, &keys, 11).await;
    publish_garbage(forged, &keys, 13).await;
    publish_garbage(plain, &keys, 17).await;
    publish_garbage(camera, &keys, 5).await;
    // Once the camera's five are counted, one more counters message: a refused peer's
    // message that got through would have been counted by then as well.
    let counted = wait_counted(&diagnostics, "bad_message/", 5).await;
    assert!(
        counted >= 5,
        "{counted} of the camera's 5 bad messages counted"
    );
    let _ = tokio::time::timeout(Duration::from_secs(5), diagnostics.recv_async()).await;
    stop_tx.send(()).unwrap();
    let summary = node.await.unwrap().unwrap();
    assert_eq!(
        summary.counters.sum("bad_message/"),
        5,
        "{:?}",
        summary.counters
    );
    let _ = std::fs::remove_dir_all(dir);
}

/// `stereosplat run` on `endpoint`, its stderr piped.
fn spawn_node(endpoint: &str, out: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_stereosplat"))
        .args([
            "run",
            "--listen",
            endpoint,
            "--method",
            "sgm",
            "--renders",
            "off",
        ])
        .arg("--out")
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

#[test]
fn a_second_node_on_a_port_in_use_fails_before_it_is_ready() {
    let dir = temp_dir("port-in-use");
    let endpoint = format!("tcp/127.0.0.1:{}", net_support::free_port());
    let mut first = spawn_node(&endpoint, &dir.join("first"));
    let mut lines = BufReader::new(first.stderr.take().unwrap()).lines();
    let ready = lines.find(|l| l.as_ref().is_ok_and(|l| l.starts_with("node ready")));
    assert!(ready.is_some(), "the first node says it is ready");

    let second = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
        .args([
            "run",
            "--listen",
            &endpoint,
            "--method",
            "sgm",
            "--renders",
            "off",
        ])
        .arg("--out")
        .arg(dir.join("second"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&second.stderr);
    assert!(
        !second.status.success(),
        "the second node exits non-zero:\n{err}"
    );
    assert!(!err.contains("node ready"), "{err}");
    assert!(
        err.contains(&endpoint),
        "the error names the endpoint:\n{err}"
    );
    assert!(err.contains("Address already in use"), "{err}");

    // The first is unharmed and stops cleanly.
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(first.id() as i32),
        nix::sys::signal::Signal::SIGTERM,
    )
    .unwrap();
    assert!(first.wait().unwrap().success());
    let _ = std::fs::remove_dir_all(dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_on_a_port_in_use_is_a_typed_error_naming_it() {
    let endpoint = format!("tcp/127.0.0.1:{}", net_support::free_port());
    let config = TransportConfig {
        listen: vec![endpoint.clone()],
        ..TransportConfig::default()
    };
    let first = open(&config).await.unwrap();
    match open(&config).await {
        Err(TransportError::Open { listen, source }) => {
            assert_eq!(listen, endpoint);
            assert!(
                source.to_string().contains("Address already in use"),
                "{source}"
            );
        }
        Ok(_) => panic!("a second session bound {endpoint}"),
        Err(other) => panic!("expected Open, got {other}"),
    }
    first.close().await.unwrap();
}

/// The `--tls-*` flags of `files`.
fn tls_flags(files: &TlsFiles) -> Vec<String> {
    let path = |p: &Path| p.display().to_string();
    vec![
        "--tls-ca".into(),
        path(&files.ca),
        "--tls-cert".into(),
        path(&files.cert),
        "--tls-key".into(),
        path(&files.key),
    ]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn in_the_secure_profile_a_worker_takes_bins_with_its_own_certificate_on_its_own_key() {
    let dir = temp_dir("zenoh-secure-workers");
    let ca = Authority::new(&dir, "ca");
    let endpoint = format!("tls/127.0.0.1:{}", net_support::free_port());
    let keys = Keys::default();
    let config = NodeConfig {
        transport: TransportConfig {
            listen: vec![endpoint.clone()],
            tls: Some(ca.identity("stereosplat-node", &ca.ca())),
            access_control: Some(PathBuf::from(ACL)),
            ..TransportConfig::default()
        },
        method: "sgm".into(),
        renders: RenderWith::Off,
        queue_capacity: 64,
        workers: WorkersConfig {
            local: false,
            ..WorkersConfig::default()
        },
        ..NodeConfig::default()
    };
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let (ready_tx, ready_rx) = tokio::sync::oneshot::channel::<()>();
    let node = tokio::spawn(node::service::run_announced(
        config,
        async {
            let _ = stop_rx.await;
        },
        move |_: &zenoh::Session| {
            let _ = ready_tx.send(());
        },
    ));
    ready_rx.await.expect("the node starts");

    // Workers with certificates of the node's authority: worker a with its own, one with
    // a's certificate announcing itself as b, one with the viewer's.
    let worker = |cn: &str, id: &str| {
        let mut args: Vec<String> = ["--connect", &endpoint, "--method", "sgm", "--id", id]
            .map(String::from)
            .to_vec();
        args.extend(["--renders".into(), "off".into()]);
        args.extend(tls_flags(&ca.identity(cn, &ca.ca())));
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        WorkerProcess::spawn(&refs)
    };
    let _a = worker("stereosplat-worker-a", "a");
    let _posing = worker("stereosplat-worker-a", "b");
    let _viewer = worker("stereosplat-viewer", "viewer");

    let drive = Drive::small("secure-workers");
    let camera = Player::with(
        &TransportConfig {
            connect: vec![endpoint.clone()],
            tls: Some(ca.identity("stereosplat-camera", &ca.ca())),
            ..TransportConfig::default()
        },
        keys.clone(),
    )
    .await;
    assert!(sees_a_subscriber(&camera.session, &keys.left_image()).await);
    // A viewer waits for every bin's pose before the node is stopped.
    let viewer = open(&TransportConfig {
        connect: vec![endpoint.clone()],
        tls: Some(ca.identity("stereosplat-viewer", &ca.ca())),
        ..TransportConfig::default()
    })
    .await
    .unwrap();
    let poses = viewer.declare_subscriber(keys.bin_pose()).await.unwrap();
    camera.frames(&drive.rig, &drive.frames).await;
    let opened = drive.bins_opened(8.0);
    for n in 0..opened {
        let pose = tokio::time::timeout(Duration::from_secs(120), poses.recv_async()).await;
        assert!(matches!(pose, Ok(Ok(_))), "{n} of {opened} bin poses");
    }
    stop_tx.send(()).unwrap();
    let summary = node.await.unwrap().unwrap();
    let c = &summary.counters;
    assert_eq!(
        summary.bins_published,
        drive.bins_opened(8.0) as u64,
        "{c:?}"
    );
    assert_eq!(c.get("workers/joined"), 1, "{c:?}");
    assert_eq!(c.get("workers/bins/a"), summary.bins_published);
    assert_eq!(c.get("workers/bins/b"), 0);
    assert_eq!(c.get("workers/bins/viewer"), 0);
    let _ = std::fs::remove_dir_all(dir);
}
