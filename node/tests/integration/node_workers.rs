//! Bins on worker processes (`stereosplat worker`, real processes of the built binary) on
//! loopback: two workers make the same maps and renders, byte for byte, as the node's own
//! worker thread, published in bin order; a worker killed (SIGKILL) while it holds a bin
//! loses no bin; a stalled worker (SIGSTOP) has its bin given to another and its late
//! answer discarded and counted; a worker with another preset is refused, says why, and
//! gets no bin; a worker at another thread count makes the same maps within a stated float
//! tolerance.

use crate::drive_support;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use drive_support::{bin_of_frame_id, wait_for, Collector, Drive, Player, RunningNode};
use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;
use node::msg::gaussians::records_from_cloud;
use node::msg::latency::Diagnostics;
use node::msg::sensor_msgs::{Image, PointCloud2};
use node::msg::Message;
use node::pipeline::worker::RenderWith;
use node::service::{NodeConfig, NodeSummary, WorkersConfig};
use node::transport::Keys;

/// A `stereosplat worker` process, killed when dropped.
pub(crate) struct WorkerProcess {
    child: Child,
    stderr: Arc<Mutex<String>>,
}

impl WorkerProcess {
    /// Starts a worker connected to `node` with the default reconstructor and, unless
    /// `extra` says otherwise, as many threads as this process's rayon pool (the node's own
    /// thread uses those), plus `extra` flags; waits until it says it is ready.
    fn start(node: &RunningNode, id: &str, extra: &[&str]) -> Self {
        let threads = rayon::current_num_threads().to_string();
        let mut args = vec![
            "--connect",
            &node.endpoint,
            "--namespace",
            &node.keys.namespace,
        ];
        args.extend(["--id", id]);
        if !extra.contains(&"--threads") {
            args.extend(["--threads", &threads]);
        }
        args.extend(extra);
        Self::spawn(&args)
    }

    /// Starts `stereosplat worker ARGS`; waits (60 s at most) until it says it is ready.
    pub(crate) fn spawn(args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_stereosplat"))
            .arg("worker")
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stderr = Arc::new(Mutex::new(String::new()));
        let (lines, pipe) = (Arc::clone(&stderr), child.stderr.take().unwrap());
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                if line.starts_with("worker ready") {
                    let _ = ready_tx.send(());
                }
                let mut all = lines.lock().unwrap();
                all.push_str(&line);
                all.push('\n');
            }
        });
        let ready = ready_rx.recv_timeout(Duration::from_secs(60));
        assert!(ready.is_ok(), "worker {args:?}: {}", stderr.lock().unwrap());
        Self { child, stderr }
    }

    fn signal(&self, signal: Signal) {
        kill(Pid::from_raw(self.child.id() as i32), signal).unwrap();
    }

    fn stderr(&self) -> String {
        self.stderr.lock().unwrap().clone()
    }
}

impl Drop for WorkerProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A node with `workers`, a queue long enough that no bin of the small drive is dropped,
/// and counters on `diagnostics` every 100 ms.
async fn node(tag: &str, workers: WorkersConfig) -> RunningNode {
    RunningNode::start(NodeConfig {
        keys: Keys::new(tag),
        queue_capacity: 64,
        renders: RenderWith::Auto,
        diagnostics_every: Duration::from_millis(100),
        workers,
        ..NodeConfig::default()
    })
    .await
}

fn remote_only(timeout: Duration) -> WorkersConfig {
    WorkersConfig {
        local: false,
        timeout,
    }
}

/// The node's counter `name` in its last diagnostics message (0 before any).
pub(crate) fn counter(outputs: &Collector, keys: &Keys, name: &str) -> u64 {
    let last = outputs.decoded::<Diagnostics>(&keys.diagnostics()).pop();
    last.and_then(|d| d.counters.into_iter().find(|c| c.kind == name))
        .map_or(0, |c| c.count)
}

/// Waits (60 s at most) until counter `name` reaches `at_least`.
pub(crate) async fn wait_counter(
    outputs: &Collector,
    keys: &Keys,
    name: &str,
    at_least: u64,
) -> bool {
    wait_for(Duration::from_secs(60), || {
        counter(outputs, keys, name) >= at_least
    })
    .await
}

type Published = (
    NodeSummary,
    BTreeMap<u64, Vec<u8>>,
    BTreeMap<u64, Vec<u8>>,
    Vec<u64>,
);

/// Plays the drive into `node` and waits for every bin's map and render.
async fn feed(node: &RunningNode, outputs: &Collector, drive: &Drive) {
    let keys = &node.keys;
    let opened = drive.bins_opened(8.0);
    let player = Player::connect(node).await;
    player.frames(&drive.rig, &drive.frames).await;
    assert!(
        outputs.wait_count(&keys.bin_map(), opened).await,
        "{} of {opened} maps",
        outputs.count(&keys.bin_map())
    );
    assert!(outputs.wait_count(&keys.bin_render(), opened).await);
}

/// Stops `node`; returns its summary and the maps and renders by bin, with the bin order
/// the maps arrived in, after checking each bin was published once.
async fn finish(node: RunningNode, outputs: &Collector, drive: &Drive) -> Published {
    let keys = node.keys.clone();
    let summary = node.stop().await;
    let (mut maps, mut renders, mut order) = (BTreeMap::new(), BTreeMap::new(), Vec::new());
    for (key, payload) in outputs.all() {
        if key == keys.bin_map() {
            let bin = bin_of_frame_id(&PointCloud2::decode(&payload).unwrap().header.frame_id);
            order.push(bin);
            assert!(
                maps.insert(bin, payload).is_none(),
                "bin {bin} published twice"
            );
        } else if key == keys.bin_render() {
            let bin = bin_of_frame_id(&Image::decode(&payload).unwrap().header.frame_id);
            assert!(renders.insert(bin, payload).is_none(), "render {bin} twice");
        }
    }
    let opened = drive.bins_opened(8.0);
    assert_eq!(maps.len(), opened);
    assert_eq!(summary.bins_published, opened as u64);
    (summary, maps, renders, order)
}

/// [`feed`], then [`finish`].
async fn play(node: RunningNode, outputs: &Collector, drive: &Drive) -> Published {
    feed(&node, outputs, drive).await;
    finish(node, outputs, drive).await
}

fn watched(node: &RunningNode) -> Vec<String> {
    let k = &node.keys;
    vec![k.bin_map(), k.bin_render(), k.diagnostics()]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_worker_processes_make_the_maps_and_renders_of_the_node_own_thread_in_bin_order() {
    let drive = Drive::small("workers-same");
    let own = node("workers-same-own", WorkersConfig::default()).await;
    let own_outputs = Collector::connect(&own, &watched(&own)).await;
    let (_, own_maps, own_renders, _) = play(own, &own_outputs, &drive).await;

    let remote = node("workers-same-remote", remote_only(Duration::from_secs(60))).await;
    let outputs = Collector::connect(&remote, &watched(&remote)).await;
    let _a = WorkerProcess::start(&remote, "a", &[]);
    let _b = WorkerProcess::start(&remote, "b", &[]);
    assert!(wait_counter(&outputs, &remote.keys, "workers/ready", 2).await);
    let (summary, maps, renders, order) = play(remote, &outputs, &drive).await;

    let c = &summary.counters;
    assert!(
        c.get("workers/bins/a") > 0 && c.get("workers/bins/b") > 0,
        "{c:?}"
    );
    assert_eq!(
        c.get("workers/bins/a") + c.get("workers/bins/b"),
        maps.len() as u64
    );
    assert!(
        order.windows(2).all(|w| w[0] < w[1]),
        "published as {order:?}"
    );
    assert_eq!(
        maps.keys().collect::<Vec<_>>(),
        own_maps.keys().collect::<Vec<_>>()
    );
    for (bin, map) in &maps {
        assert!(map == &own_maps[bin], "bin {bin}'s map differs");
        assert!(
            renders[bin] == own_renders[bin],
            "bin {bin}'s render differs"
        );
    }
}

/// A node with no thread of its own and `timeout`, workers `a` and `b` that have joined,
/// `a` frozen (SIGSTOP): the first bin goes to `a`, which holds it.
async fn a_frozen(tag: &str, timeout: Duration) -> (RunningNode, Collector, [WorkerProcess; 2]) {
    let node = node(tag, remote_only(timeout)).await;
    let outputs = Collector::connect(&node, &watched(&node)).await;
    let a = WorkerProcess::start(&node, "a", &[]);
    let b = WorkerProcess::start(&node, "b", &[]);
    assert!(wait_counter(&outputs, &node.keys, "workers/ready", 2).await);
    a.signal(Signal::SIGSTOP);
    (node, outputs, [a, b])
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_killed_while_it_holds_a_bin_loses_no_bin() {
    let drive = Drive::small("workers-kill");
    // Frozen, `a` takes its first bin and holds it; then it dies with it.
    let (node, outputs, [a, _b]) = a_frozen("workers-kill", Duration::from_secs(60)).await;
    let keys = node.keys.clone();
    let killer = async {
        assert!(wait_counter(&outputs, &keys, "workers/bins/a", 1).await);
        a.signal(Signal::SIGKILL);
    };
    tokio::join!(feed(&node, &outputs, &drive), killer);
    let (summary, ..) = finish(node, &outputs, &drive).await;
    let c = &summary.counters;
    // Every bin `a` took went to `b`, which made them all.
    assert_eq!(c.get("workers/bins/a"), 1, "{c:?}");
    assert_eq!(c.get("workers/reassigned"), 1);
    assert_eq!(c.get("workers/bins/b"), drive.bins_opened(8.0) as u64);
    assert_eq!(c.get("workers/left"), 1);
    assert_eq!(c.get("discarded/late_bin"), 0);
    assert_eq!(c.get("dropped/worker_queue"), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_worker_bin_goes_to_another_and_its_late_answer_is_discarded() {
    let drive = Drive::small("workers-stall");
    let (node, outputs, [a, _b]) = a_frozen("workers-stall", Duration::from_secs(1)).await;
    let keys = node.keys.clone();
    let thaw = async {
        // `a` holds its bin past the 1 s timeout; once the bin has gone to `b`, `a` wakes
        // (well within zenoh's 10 s lease, so it stays connected) and answers late.
        assert!(wait_counter(&outputs, &keys, "workers/stalled", 1).await);
        a.signal(Signal::SIGCONT);
        assert!(wait_counter(&outputs, &keys, "discarded/late_bin", 1).await);
    };
    // The node stops once the late answer is in.
    tokio::join!(thaw, feed(&node, &outputs, &drive));
    let (summary, ..) = finish(node, &outputs, &drive).await;
    let c = &summary.counters;
    // On a loaded machine `b` too can hold a bin past the 1 s timeout (seen beside two busy
    // loops: 2 stalls, 2 reassigned, 2 late answers): each stall then goes the same way.
    let stalled = c.get("workers/stalled");
    assert!(stalled >= 1, "{c:?}");
    assert_eq!(c.get("workers/reassigned"), stalled, "{c:?}");
    assert!(
        (1..=stalled).contains(&c.get("discarded/late_bin")),
        "{c:?}"
    );
    assert_eq!(c.get("workers/left"), 0, "{c:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_with_another_preset_is_refused_and_gets_no_bin() {
    let drive = Drive::small("workers-refused");
    let node = node("workers-refused", WorkersConfig::default()).await;
    let outputs = Collector::connect(&node, &watched(&node)).await;
    let other = WorkerProcess::start(&node, "other", &["--preset", "tiny-3d"]);
    assert!(wait_counter(&outputs, &node.keys, "refused/worker", 1).await);
    let (summary, ..) = play(node, &outputs, &drive).await;
    let c = &summary.counters;
    assert_eq!(c.get("refused/worker"), 1, "{c:?}");
    assert_eq!(c.get("workers/joined"), 0);
    assert_eq!(c.get("workers/bins/other"), 0);
    let said = other.stderr();
    assert!(
        said.contains("refused: this worker runs stereosplat preset tiny-3d")
            && said.contains("the node asks for stereosplat preset tiny "),
        "{said}"
    );
}

/// The largest difference, field by field, between the records of two bin maps of the same
/// length (positions in metres, scales as logs, opacity as a logit, colours as SH DC).
fn max_field_difference(a: &[u8], b: &[u8]) -> Option<[f64; 15]> {
    let records = |p: &[u8]| records_from_cloud(&PointCloud2::decode(p).unwrap()).unwrap();
    let (a, b) = (records(a), records(b));
    if a.len() != b.len() {
        return None;
    }
    let mut max = [0.0f64; 15];
    for (x, y) in a.iter().zip(&b) {
        for (m, (u, v)) in max.iter_mut().zip(x.iter().zip(y)) {
            *m = m.max((u - v).abs());
        }
    }
    Some(max)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_at_another_thread_count_makes_the_same_maps_within_a_float_tolerance() {
    let drive = Drive::small("workers-threads");
    let own = node("workers-threads-own", WorkersConfig::default()).await;
    let own_outputs = Collector::connect(&own, &watched(&own)).await;
    let (_, own_maps, ..) = play(own, &own_outputs, &drive).await;

    let remote = node(
        "workers-threads-remote",
        remote_only(Duration::from_secs(60)),
    )
    .await;
    let outputs = Collector::connect(&remote, &watched(&remote)).await;
    // Another thread count than the node's own thread ran with.
    let other = if rayon::current_num_threads() == 1 {
        "2"
    } else {
        "1"
    };
    let _a = WorkerProcess::start(&remote, "a", &["--threads", other]);
    assert!(wait_counter(&outputs, &remote.keys, "workers/ready", 1).await);
    let (_, maps, ..) = play(remote, &outputs, &drive).await;
    for (bin, map) in &maps {
        let diff = max_field_difference(map, &own_maps[bin])
            .unwrap_or_else(|| panic!("bin {bin}: another number of Gaussians"));
        println!("bin {bin}: largest difference per field {diff:?}");
        let position = diff[..3].iter().copied().fold(0.0, f64::max);
        let rest = diff[3..].iter().copied().fold(0.0, f64::max);
        assert!(position <= 1e-3 && rest <= 1e-3, "bin {bin}: {diff:?}");
    }
}
