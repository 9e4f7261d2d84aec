//! Worker replies cannot corrupt the map. On loopback, a rogue peer poses as worker
//! processes: a real zenoh session that declares liveliness tokens under the node's
//! workers key, answers the greeting with the node's fingerprint and answers bins, one id
//! with a map a kilometre from the bin, one with confidences of 1e30, one with a reply
//! just over the bin's size limit; and it answers on an honest worker's key too. The node
//! fuses none of it, counts each, expels the three rogues, keeps running, and its bin maps
//! and map updates are byte for byte those of a run of the same drive without the rogue.

use crate::drive_support;
use crate::node_workers::{counter, wait_counter};

use std::collections::BTreeMap;
use std::time::Duration;

use drive_support::{bin_of_frame_id, Collector, Drive, Player, RunningNode};
use glam::{DAffine3, DVec3, Quat, Vec3};
use model::consistency::{CheckReport, Verdict};
use node::msg::sensor_msgs::PointCloud2;
use node::msg::Message;
use node::pipeline::operating::PointRunner;
use node::pipeline::self_check::{CheckAction, CheckOutcome};
use node::pipeline::worker::{Output, RenderWith};
use node::remote::admit::{max_gaussians, reply_limit};
use node::remote::wire::{BinJob, Hello, Reply, Request};
use node::remote::{serve, Fingerprint, ServeConfig};
use node::service::{NodeConfig, NodeSummary};
use node::transport::open;
use node::transport::Keys;
use renderer::gaussians::Gaussian;
use renderer::GaussianSet;
use zenoh::liveliness::LivelinessToken;
use zenoh::query::Query;
use zenoh::Session;

/// What a rogue queryable answers a bin with.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Attack {
    /// A plausible map a kilometre from the bin.
    FarPose,
    /// A map at the bin's pose whose confidences are 1e30.
    Confident,
    /// A reply 1 MiB over the bin's size limit.
    Huge,
    /// On an honest worker's key (without a token, quiet at the greeting): a far map.
    Shadow,
}

/// The node of both runs: SGM, no renders, its own thread on, a queue no bin of the small
/// drive overflows, counters every 100 ms.
async fn node(tag: &str) -> RunningNode {
    RunningNode::start(NodeConfig {
        keys: Keys::new(tag),
        method: "sgm".into(),
        renders: RenderWith::Off,
        queue_capacity: 64,
        diagnostics_every: Duration::from_millis(100),
        ..NodeConfig::default()
    })
    .await
}

fn fingerprint() -> Fingerprint {
    Fingerprint::of(&"sgm".into()).unwrap()
}

/// 64 opaque Gaussians 6 m ahead of the bin's camera, each of `confidence`, and a passing
/// self-check said of them.
fn forged_map(job: &BinJob, pose: DAffine3, confidence: f32) -> Vec<u8> {
    let mut set = GaussianSet::default();
    for i in 0..64 {
        set.push(Gaussian {
            mean: Vec3::new((i % 8) as f32 - 4.0, (i / 8) as f32 * 0.5 - 2.0, 6.0),
            log_scale: Vec3::splat(-2.0),
            rotation: Quat::IDENTITY,
            opacity: 0.9,
            color: Vec3::splat(0.5),
            confidence,
        });
    }
    let passing = CheckReport {
        score: 1.0,
        coverage: 1.0,
        samples: 64,
        textured: 64,
        verdict: Verdict::Pass,
    };
    let out = Output {
        bin_id: job.bin_id,
        bin_to_world: pose,
        result: Ok(set),
        check: CheckOutcome {
            primary: Some(passing),
            action: CheckAction::None,
            fallback: None,
        },
        render_follows: false,
        stamps: job.stamps,
        queue_depth: 0,
        point: 0,
    };
    Reply::Map(job.attempt, Box::new(out)).encode()
}

/// Answers `query` as `attack` says.
async fn answer(query: Query, attack: Attack) {
    let bytes = query.payload().map(|p| p.to_bytes().into_owned());
    let job = match Request::decode(&bytes.unwrap_or_default()) {
        Ok(Request::Bin(job)) => job,
        Ok(Request::Hello(_)) if attack != Attack::Shadow => {
            let me = Hello {
                fingerprint: fingerprint(),
                threads: 1,
            };
            let _ = query
                .reply(query.key_expr().clone(), Reply::Hello(me).encode())
                .await;
            return;
        }
        _ => return,
    };
    let pose = job.frame.left_to_world;
    let far = DAffine3::from_translation(DVec3::new(1000.0, 0.0, 0.0)) * pose;
    let payload = match attack {
        Attack::FarPose | Attack::Shadow => forged_map(&job, far, 0.9),
        Attack::Confident => forged_map(&job, pose, 1e30),
        Attack::Huge => {
            let (w, h) = (job.frame.left.width, job.frame.left.height);
            vec![0x5a; reply_limit(max_gaussians(&fingerprint()), w, h) + (1 << 20)]
        }
    };
    let _ = query.reply(query.key_expr().clone(), payload).await;
}

/// Declares a queryable on worker `id`'s key answering as `attack` says (until the session
/// closes) and, but for the shadow, the worker's liveliness token.
async fn pose_as(
    session: &Session,
    keys: &Keys,
    id: &str,
    attack: Attack,
) -> Option<LivelinessToken> {
    let key = keys.worker(id);
    let queries = session.declare_queryable(key.clone()).await.unwrap();
    tokio::spawn(async move {
        while let Ok(query) = queries.recv_async().await {
            answer(query, attack).await;
        }
    });
    match attack {
        Attack::Shadow => None,
        _ => Some(session.liveliness().declare_token(key).await.unwrap()),
    }
}

/// What a run published: its summary, the bin maps by bin, the map updates in order.
struct Published {
    summary: NodeSummary,
    maps: BTreeMap<u64, Vec<u8>>,
    updates: Vec<Vec<u8>>,
}

fn watched(keys: &Keys) -> Vec<String> {
    vec![keys.bin_map(), keys.map_update(), keys.diagnostics()]
}

/// Plays `drive` into `node`, waits for every bin's map (and `wait` before stopping), and
/// stops it.
async fn play(node: RunningNode, outputs: &Collector, drive: &Drive, wait: &[&str]) -> Published {
    let keys = node.keys.clone();
    let opened = drive.bins_opened(8.0);
    let player = Player::connect(&node).await;
    player.frames(&drive.rig, &drive.frames).await;
    assert!(
        outputs.wait_count(&keys.bin_map(), opened).await,
        "{} of {opened} maps",
        outputs.count(&keys.bin_map())
    );
    for name in wait {
        assert!(
            wait_counter(outputs, &keys, name, 1).await,
            "counter {name}"
        );
    }
    assert!(node.is_running(), "the node keeps running");
    let summary = node.stop().await;
    let (mut maps, mut updates) = (BTreeMap::new(), Vec::new());
    for (key, payload) in outputs.all() {
        if key == keys.bin_map() {
            let bin = bin_of_frame_id(&PointCloud2::decode(&payload).unwrap().header.frame_id);
            assert!(maps.insert(bin, payload).is_none(), "bin {bin} twice");
        } else if key == keys.map_update() {
            updates.push(payload);
        }
    }
    assert_eq!(maps.len(), opened);
    Published {
        summary,
        maps,
        updates,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rogue_posing_as_workers_fuses_nothing_and_the_map_is_the_node_own() {
    let started = std::time::Instant::now();
    let drive = Drive::small("workers-rogue");
    let own = node("workers-rogue-own").await;
    let own_outputs = Collector::connect(&own, &watched(&own.keys)).await;
    let alone = play(own, &own_outputs, &drive, &[]).await;

    let node = node("workers-rogue").await;
    let keys = node.keys.clone();
    let outputs = Collector::connect(&node, &watched(&keys)).await;
    // The rogue's replies on the honest worker's key are declared first, so the node knows
    // them before it sends that worker anything.
    let rogue = open(&node.client()).await.unwrap();
    pose_as(&rogue, &keys, "z-honest", Attack::Shadow).await;
    let mut tokens = Vec::new();
    for (id, attack) in [
        ("a-pose", Attack::FarPose),
        ("b-confident", Attack::Confident),
        ("c-huge", Attack::Huge),
    ] {
        tokens.extend(pose_as(&rogue, &keys, id, attack).await);
    }
    // An honest worker in this process (the node's SGM, at the node's thread count).
    let (stop_honest, stopped) = tokio::sync::oneshot::channel::<()>();
    let honest = tokio::spawn(serve(
        ServeConfig {
            transport: node.client(),
            keys: keys.clone(),
            id: "z-honest".into(),
            renders: RenderWith::Off,
            threads: rayon::current_num_threads() as u32,
        },
        PointRunner::whole(model::methods::by_name("sgm").unwrap()),
        fingerprint(),
        async {
            let _ = stopped.await;
        },
        |_| {},
    ));
    assert!(wait_counter(&outputs, &keys, "workers/ready", 4).await);
    assert_eq!(counter(&outputs, &keys, "refused/worker"), 0);

    // Workers are served in id order: the rogues take the first bins.
    let waited = [
        "discarded/worker_pose",
        "discarded/worker_values",
        "discarded/worker_reply_size",
        "discarded/worker_replier",
    ];
    let attacked = play(node, &outputs, &drive, &waited).await;
    let _ = stop_honest.send(());
    let served = honest.await.unwrap().unwrap();
    drop(tokens);
    rogue.close().await.unwrap();

    let c = &attacked.summary.counters;
    for name in &waited[..3] {
        assert_eq!(c.get(name), 1, "{name}: {c:?}");
    }
    assert!(c.get("discarded/worker_replier") >= 1, "{c:?}");
    assert_eq!(c.get("workers/expelled"), 3, "{c:?}");
    for id in ["a-pose", "b-confident", "c-huge"] {
        assert_eq!(c.get(&format!("workers/bins/{id}")), 1, "{id}: {c:?}");
    }
    assert_eq!(c.get("workers/reassigned"), 3, "{c:?}");
    assert_eq!(c.get("error/worker_reply"), 0, "{c:?}");
    assert!(served.bins >= 1, "the honest worker made bins: {served:?}");

    // The map is the node's own: every bin map and map update byte for byte.
    assert_eq!(
        attacked.maps.keys().collect::<Vec<_>>(),
        alone.maps.keys().collect::<Vec<_>>()
    );
    for (bin, map) in &attacked.maps {
        assert!(map == &alone.maps[bin], "bin {bin}'s map differs");
    }
    assert_eq!(attacked.updates.len(), alone.updates.len());
    assert!(attacked.updates == alone.updates, "the map updates differ");
    assert_eq!(
        attacked.summary.global_gaussians,
        alone.summary.global_gaussians
    );
    println!("rogue test: {:.1} s", started.elapsed().as_secs_f64());
}
