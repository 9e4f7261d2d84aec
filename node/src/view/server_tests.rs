//! The view's server over raw TCP on 127.0.0.1: what it guarantees a browser (HEAD, 404,
//! no path outside the table) and what bounds it keeps against clients that misbehave (a
//! slow request head, an oversized one, more connections than slots).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

use super::routes;
use super::server::{serve, Limits};
use super::state::ViewState;

/// Longest a well-behaved exchange may take here.
const PATIENCE: Duration = Duration::from_secs(5);

/// A `node_modules` folder with the three library files, and a secret file beside it that
/// no request may reach.
fn libraries() -> PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let root = std::env::temp_dir().join(format!(
        "ss-view-test-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let modules = root.join("node_modules");
    for file in [
        "three/build/three.module.js",
        "three/build/three.core.js",
        "@mkkellogg/gaussian-splats-3d/build/gaussian-splats-3d.module.js",
    ] {
        let path = modules.join(file);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, format!("// {file}\n")).unwrap();
    }
    std::fs::write(root.join("secret.txt"), "SECRET\n").unwrap();
    std::fs::write(modules.join("secret.txt"), "SECRET\n").unwrap();
    modules
}

/// Starts a server within `limits` on a free loopback port, with a render picture of bin 7
/// in its state. The server stops when the test's runtime ends.
async fn start(limits: Limits) -> SocketAddr {
    let mut state = ViewState::default();
    state.render(7, 0, b"not really a png".to_vec());
    start_with(state, limits).await
}

/// Starts a server on `state` on a free loopback port, with the default limits.
async fn start_on(state: ViewState) -> SocketAddr {
    start_with(state, Limits::default()).await
}

async fn start_with(state: ViewState, limits: Limits) -> SocketAddr {
    let router = routes::router(Arc::new(Mutex::new(state)), libraries());
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(serve(listener, router, limits, std::future::pending()));
    addr
}

/// One answer: status, headers (names lower-cased) and body.
#[derive(Debug)]
struct Answer {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Answer {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// Everything the server writes on `stream` until it closes, split into an [`Answer`].
async fn read_answer(stream: &mut TcpStream) -> Answer {
    let mut raw = Vec::new();
    tokio::time::timeout(PATIENCE, stream.read_to_end(&mut raw))
        .await
        .expect("the server closes the connection after its answer")
        .unwrap();
    let end = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("no end of head in {:?}", String::from_utf8_lossy(&raw)));
    let head = std::str::from_utf8(&raw[..end]).unwrap();
    let mut lines = head.split("\r\n");
    let status = lines.next().unwrap().split(' ').nth(1).unwrap();
    let headers = lines
        .map(|l| {
            let (n, v) = l.split_once(':').unwrap();
            (n.trim().to_ascii_lowercase(), v.trim().to_string())
        })
        .collect();
    Answer {
        status: status.parse().unwrap(),
        headers,
        body: raw[end + 4..].to_vec(),
    }
}

/// Sends `method path` on a fresh connection and reads the answer.
async fn request(addr: SocketAddr, method: &str, path: &str) -> Answer {
    let mut stream = TcpStream::connect(addr).await.unwrap();
    let req = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n");
    stream.write_all(req.as_bytes()).await.unwrap();
    read_answer(&mut stream).await
}

#[tokio::test]
async fn every_route_answers_get_with_its_type_and_the_shared_headers() {
    let addr = start(Limits::default()).await;
    for (path, status, content_type) in [
        ("/", 200, "text/html; charset=utf-8"),
        ("/index.html", 200, "text/html; charset=utf-8"),
        ("/app.js", 200, "text/javascript; charset=utf-8"),
        ("/favicon.ico", 200, "image/x-icon"),
        ("/api/state", 200, "application/json"),
        ("/api/state?t=1", 200, "application/json"),
        ("/map.ply", 404, "text/plain; charset=utf-8"),
        ("/render.png", 200, "image/png"),
        ("/input.png", 404, "text/plain; charset=utf-8"),
        ("/bev.png", 404, "text/plain; charset=utf-8"),
        (
            "/lib/three/three.module.js",
            200,
            "text/javascript; charset=utf-8",
        ),
        (
            "/lib/three/three.core.js",
            200,
            "text/javascript; charset=utf-8",
        ),
        (
            "/lib/splats/gaussian-splats-3d.module.js",
            200,
            "text/javascript; charset=utf-8",
        ),
    ] {
        let a = request(addr, "GET", path).await;
        assert_eq!(a.status, status, "{path}: {a:?}");
        assert_eq!(a.header("content-type"), Some(content_type), "{path}");
        assert_eq!(a.header("cache-control"), Some("no-store"), "{path}");
        assert_eq!(
            a.header("x-content-type-options"),
            Some("nosniff"),
            "{path}"
        );
        assert_eq!(a.header("connection"), Some("close"), "{path}");
        assert_eq!(
            a.header("content-length"),
            Some(a.body.len().to_string().as_str()),
            "{path}"
        );
    }
    let state: serde_json::Value =
        serde_json::from_slice(&request(addr, "GET", "/api/state").await.body).unwrap();
    assert!(state.is_object(), "{state}");
    let render = request(addr, "GET", "/render.png").await;
    assert_eq!(render.body, b"not really a png");
    assert_eq!(render.header("x-bin-id"), Some("7"));
    let lib = request(addr, "GET", "/lib/three/three.core.js").await;
    assert_eq!(lib.body, b"// three/build/three.core.js\n");
}

#[tokio::test]
async fn a_request_naming_another_host_is_refused_before_any_route() {
    let addr = start(Limits::default()).await;
    for (host, status) in [
        ("rebound.attacker.example", 421),
        (&*format!("localhost:{}", addr.port()), 200),
    ] {
        let mut stream = TcpStream::connect(addr).await.unwrap();
        let req = format!("GET /api/state HTTP/1.1\r\nHost: {host}\r\n\r\n");
        stream.write_all(req.as_bytes()).await.unwrap();
        assert_eq!(read_answer(&mut stream).await.status, status, "{host}");
    }
}

#[tokio::test]
async fn head_has_get_s_headers_and_no_body() {
    let addr = start(Limits::default()).await;
    for path in [
        "/",
        "/api/state",
        "/render.png",
        "/lib/three/three.core.js",
        "/nope",
    ] {
        let get = request(addr, "GET", path).await;
        let head = request(addr, "HEAD", path).await;
        assert_eq!(head.status, get.status, "{path}");
        assert!(head.body.is_empty(), "{path}: {head:?}");
        for name in [
            "content-type",
            "content-length",
            "cache-control",
            "x-bin-id",
        ] {
            assert_eq!(head.header(name), get.header(name), "{path}: {name}");
        }
        assert!(head.header("content-length").is_some(), "{path}");
    }
}

#[tokio::test]
async fn unknown_paths_404_and_other_methods_405() {
    let addr = start(Limits::default()).await;
    for path in [
        "/nope",
        "/lib/three/",
        "/lib/three/other.js",
        "/api/state/x",
        "/app.js/",
    ] {
        assert_eq!(request(addr, "GET", path).await.status, 404, "{path}");
    }
    for (method, path) in [("POST", "/api/state"), ("PUT", "/"), ("DELETE", "/nope")] {
        let a = request(addr, method, path).await;
        assert_eq!(a.status, 405, "{method} {path}");
        assert_eq!(a.header("cache-control"), Some("no-store"));
    }
}

#[tokio::test]
async fn no_path_reaches_a_file_outside_the_table() {
    let addr = start(Limits::default()).await;
    for path in [
        "/lib/three/../secret.txt",
        "/lib/three/../../secret.txt",
        "/lib/three/../../../secret.txt",
        "/lib/three/%2e%2e/%2e%2e/secret.txt",
        "/lib/three/..%2f..%2fsecret.txt",
        "/lib/%2e%2e/%2e%2e/%2e%2e/node_modules/secret.txt",
        "/../secret.txt",
        "/..%5csecret.txt",
        "/three/build/three.core.js",
        "/lib/three/./three.core.js",
        "/lib/three//three.core.js",
    ] {
        let a = request(addr, "GET", path).await;
        assert!(a.status == 404 || a.status == 400, "{path}: {a:?}");
        assert!(
            !String::from_utf8_lossy(&a.body).contains("SECRET"),
            "{path}: {a:?}"
        );
        assert!(!String::from_utf8_lossy(&a.body).contains("//"), "{path}");
    }
}

#[tokio::test]
async fn an_oversized_request_head_is_refused() {
    let addr = start(Limits::default()).await;
    let mut stream = TcpStream::connect(addr).await.unwrap();
    let filler = "a".repeat(Limits::default().head_bytes);
    let req = format!("GET / HTTP/1.1\r\nHost: {addr}\r\nX-Filler: {filler}\r\n\r\n");
    // The server may close before it has read everything: only the answer matters.
    let _ = stream.write_all(req.as_bytes()).await;
    assert_eq!(read_answer(&mut stream).await.status, 431);
}

#[tokio::test]
async fn a_slow_client_neither_blocks_others_nor_keeps_its_connection() {
    let read_timeout = Duration::from_millis(500);
    let addr = start(Limits {
        read_timeout,
        ..Limits::default()
    })
    .await;
    let mut slow = TcpStream::connect(addr).await.unwrap();
    slow.write_all(format!("GET / HTTP/1.1\r\nHost: {addr}\r\nX-Half: ").as_bytes())
        .await
        .unwrap();
    let started = Instant::now();
    let other = request(addr, "GET", "/api/state").await;
    assert_eq!(other.status, 200);
    assert!(started.elapsed() < read_timeout, "{:?}", started.elapsed());
    // The slow client's connection ends after the read timeout (hyper may say 408 first).
    let mut rest = Vec::new();
    tokio::time::timeout(PATIENCE, slow.read_to_end(&mut rest))
        .await
        .expect("the slow client's connection is closed")
        .unwrap();
    assert!(started.elapsed() >= read_timeout, "{:?}", started.elapsed());
    let said = String::from_utf8_lossy(&rest);
    assert!(
        rest.is_empty() || said.starts_with("HTTP/1.1 408"),
        "{said}"
    );
}

#[tokio::test]
async fn connections_beyond_the_limit_wait_for_a_free_slot() {
    let limits = Limits {
        connections: 4,
        read_timeout: Duration::from_secs(60),
        ..Limits::default()
    };
    let addr = start(limits).await;
    // Connections that send nothing hold every slot.
    let mut idle = Vec::new();
    for _ in 0..limits.connections {
        idle.push(TcpStream::connect(addr).await.unwrap());
    }
    // The operating system completes the next connection, but the server does not take it.
    let mut waiting = TcpStream::connect(addr).await.unwrap();
    let req = format!("GET /api/state HTTP/1.1\r\nHost: {addr}\r\n\r\n");
    waiting.write_all(req.as_bytes()).await.unwrap();
    let mut byte = [0u8; 1];
    let early = tokio::time::timeout(Duration::from_millis(500), waiting.read(&mut byte)).await;
    assert!(early.is_err(), "answered beyond the limit: {early:?}");
    // One idle client leaves: its slot goes to the waiting one.
    drop(idle.pop());
    assert_eq!(read_answer(&mut waiting).await.status, 200);
}

#[tokio::test]
async fn tiles_are_listed_near_a_point_and_served_one_by_one() {
    use crate::fusion::{GaussianId, Snapshot, Update, WorldGaussian};
    use glam::{DAffine3, DVec3};

    // 64 m tiles kept within 100 m of the vehicle: Gaussians at x = 1, 2 (tile 0), 70 (tile
    // 1), 1001 and a fainter one at 1003 (tile 15); the vehicle at x = 1000 lets tiles 0
    // and 1 go.
    let mut state = ViewState::with_tiles(super::TileRules {
        keep_m: 100.0,
        ..super::TileRules::default()
    });
    let g = |x: f64| super::test_gaussian::at(DVec3::new(x, 1.0, 0.5));
    let snapshot = Snapshot {
        last_bin_id: Some(0),
        gaussians: [1.0, 2.0, 70.0, 1001.0, 1003.0]
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                let opacity = if x == 1003.0 { 0.3 } else { 0.8 };
                (GaussianId(i as u64), WorldGaussian { opacity, ..g(x) })
            })
            .collect(),
    };
    state.map_update(1, Update::Snapshot(snapshot));
    state.bin_pose(0, DAffine3::from_translation(DVec3::new(1000.0, 0.0, 0.0)));
    let addr = start_on(state).await;

    // Page coordinates are relative to the origin, the first Gaussian (x = 1).
    let a = request(addr, "GET", "/api/tiles?x=999&y=0&radius=2000").await;
    assert_eq!(a.status, 200, "{a:?}");
    let listing: serde_json::Value = serde_json::from_slice(&a.body).unwrap();
    let tiles: Vec<(i64, u64, bool)> = listing["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let held = t["held"].as_bool().unwrap();
            (
                t["x"].as_i64().unwrap(),
                t["gaussians"].as_u64().unwrap(),
                held,
            )
        })
        .collect();
    assert_eq!(
        tiles,
        vec![(15, 2, true), (1, 1, false), (0, 2, false)],
        "nearest first"
    );
    // A budget of 3 takes tile 15 whole and 1 of tile 1's Gaussians; 1 takes part of 15.
    for (budget, want) in [(3, vec![(15, 2), (1, 1)]), (1, vec![(15, 1)])] {
        let uri = format!("/api/tiles?x=999&y=0&radius=2000&budget={budget}");
        let a = request(addr, "GET", &uri).await;
        let listing: serde_json::Value = serde_json::from_slice(&a.body).unwrap();
        let takes: Vec<(i64, u64)> = listing["tiles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| (t["x"].as_i64().unwrap(), t["take"].as_u64().unwrap()))
            .collect();
        assert_eq!(takes, want, "budget {budget}");
    }
    let a = request(addr, "GET", "/api/tiles?x=999&y=0&radius=10").await;
    let listing: serde_json::Value = serde_json::from_slice(&a.body).unwrap();
    assert_eq!(listing["tiles"].as_array().unwrap().len(), 1, "within 10 m");

    let a = request(addr, "GET", "/map/tile.ply?x=15&y=0&v=3").await;
    assert_eq!(a.status, 200);
    assert!(a.header("x-tile-version").is_some());
    let set = renderer::ply::read_ply(a.body.as_slice()).unwrap();
    assert_eq!(set.len(), 2);
    assert!(
        (set.means[0].x - 1000.0).abs() < 1e-3,
        "relative to the origin"
    );
    // `take` serves the tile's most opaque: the fainter Gaussian at 1003 goes first.
    let a = request(addr, "GET", "/map/tile.ply?x=15&y=0&v=3&take=1").await;
    let set = renderer::ply::read_ply(a.body.as_slice()).unwrap();
    assert_eq!(set.len(), 1);
    assert!((set.means[0].x - 1000.0).abs() < 1e-3);
    let a = request(addr, "GET", "/map/tile.ply?x=15&y=0&take=50").await;
    assert_eq!(renderer::ply::read_ply(a.body.as_slice()).unwrap().len(), 2);
    // A tile the view let go is fetched from the node: the page is told to retry.
    let a = request(addr, "GET", "/map/tile.ply?x=0&y=0").await;
    assert_eq!((a.status, a.header("retry-after")), (503, Some("1")));
    assert_eq!(
        request(addr, "GET", "/map/tile.ply?x=7&y=7").await.status,
        404
    );

    for bad in [
        "/api/tiles",
        "/api/tiles?x=1",
        "/api/tiles?x=abc&y=0",
        "/api/tiles?x=NaN&y=0",
        "/api/tiles?x=0&y=0&x=1",
        "/api/tiles?x=0&y=0&colour=red",
        "/api/tiles?x=0&y=0&radius=-1",
        "/api/tiles?x=0&y=0&budget=0",
        "/api/tiles?x=0&y=0&budget=1e300",
        "/map/tile.ply?x=0.5&y=0",
        "/map/tile.ply?x=1e300&y=0",
        "/map/tile.ply?y=0",
        "/map/tile.ply?x=0&y=0&take=0",
        "/map/tile.ply?x=0&y=0&take=1.5",
        "/map/tile.ply?x=0&y=0&take=-3",
        "/map/tile.ply?x=0&y=0&take=1e300",
    ] {
        let a = request(addr, "GET", bad).await;
        assert_eq!(a.status, 400, "{bad}: {a:?}");
        assert!(!a.body.is_empty(), "{bad}: says why");
    }
}
