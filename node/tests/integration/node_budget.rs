//! A latency budget in a real node on loopback: every bin's latency message names the
//! operating point its map was made with; a budget no point fits publishes every bin with
//! the table's fastest point and counts it; a budget everything fits runs the most accurate
//! point; and a worker slower than the table says moves the node down to a point that fits.

use crate::drive_support;

use drive_support::{Collector, Drive, Player, RunningNode};
use node::msg::latency::BinLatency;
use node::pipeline::operating::parse_points;
use node::pipeline::operating::{
    Budget, GovernorConfig, OperatingConfig, OperatingTable, TableRow,
};
use node::pipeline::worker::RenderWith;
use node::service::{NodeConfig, NodeSummary};
use node::transport::Keys;

/// `tiny` (the more accurate) and SGM at half scale (the fastest), with these table times.
fn table(tiny_ms: f64, sgm_ms: f64) -> OperatingTable {
    let points = parse_points(
        "[[point]]\nname = \"tiny\"\n\n[[point]]\nname = \"sgm-half\"\nmethod = \"sgm\"\nscale = 0.5",
    )
    .unwrap();
    let rows = points
        .into_iter()
        .zip([(tiny_ms, 24.0), (sgm_ms, 17.0)])
        .map(|(point, (ms, psnr))| TableRow { point, ms, psnr })
        .collect();
    OperatingTable::new((272, 72), "test".into(), rows).unwrap()
}

/// Runs the small drive through a node with `operating`.
async fn run(tag: &str, operating: OperatingConfig) -> (NodeSummary, Vec<BinLatency>, usize) {
    let drive = Drive::small(tag);
    let opened = drive.bins_opened(8.0);
    let keys = Keys::new(tag);
    let node = RunningNode::start(NodeConfig {
        keys: keys.clone(),
        queue_capacity: 64,
        renders: RenderWith::Off,
        operating: Some(operating),
        ..NodeConfig::default()
    })
    .await;
    let outputs = Collector::connect(&node, &[keys.latency(), keys.bin_map()]).await;
    let player = Player::connect(&node).await;
    player.frames(&drive.rig, &drive.frames).await;
    outputs.wait_count(&keys.bin_map(), opened).await;
    let summary = node.stop().await;
    // The last bin's latency goes out as the node stops.
    outputs.wait_count(&keys.latency(), opened).await;
    (summary, outputs.decoded(&keys.latency()), opened)
}

fn operating(tiny_ms: f64, sgm_ms: f64, budget: Budget) -> OperatingConfig {
    OperatingConfig {
        table: table(tiny_ms, sgm_ms),
        budget,
        governor: GovernorConfig::default(),
    }
}

fn points(latencies: &[BinLatency]) -> Vec<&str> {
    latencies
        .iter()
        .map(|l| l.operating_point.as_str())
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_budget_no_point_fits_publishes_every_bin_at_the_fastest_point_and_says_so() {
    let (summary, latencies, opened) = run(
        "budget-none-fits",
        operating(100.0, 10.0, Budget::Fixed(1.0)),
    )
    .await;
    assert_eq!(summary.bins_published, opened as u64);
    assert_eq!(latencies.len(), opened, "every bin's latency");
    assert!(
        points(&latencies).iter().all(|&p| p == "sgm-half"),
        "{:?}",
        points(&latencies)
    );
    let c = &summary.counters;
    assert_eq!(c.get("operating/no_point_fits"), opened as u64);
    assert_eq!(c.get("operating/bins/sgm-half"), opened as u64);
    assert_eq!(c.get("operating/switches"), 0);
    assert_eq!(c.get("operating/budget_ms"), 1);
    assert_eq!(c.get("dropped/worker_queue"), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_budget_every_point_fits_runs_the_most_accurate_on_every_bin() {
    let (summary, latencies, opened) =
        run("budget-all-fit", operating(100.0, 10.0, Budget::Fixed(1e9))).await;
    assert_eq!(latencies.len(), opened);
    assert!(
        points(&latencies).iter().all(|&p| p == "tiny"),
        "{:?}",
        points(&latencies)
    );
    assert_eq!(summary.counters.get("operating/bins/tiny"), opened as u64);
    assert_eq!(summary.counters.get("operating/no_point_fits"), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_slower_than_its_table_moves_down_to_a_point_that_fits() {
    // The table says tiny takes 1 ms and SGM at half scale 0.01, as if measured on a machine
    // a hundred times faster: a 20 ms budget fits both by the table. The network takes
    // several times the budget at 272x72 on a CPU; with the table scaled by what it measured,
    // only SGM (a few ms) is expected to fit, so after its first bin the node runs SGM.
    let (summary, latencies, opened) =
        run("budget-slow", operating(1.0, 0.01, Budget::Fixed(20.0))).await;
    assert_eq!(latencies.len(), opened);
    let mut by_id = latencies.clone();
    by_id.sort_by_key(|l| l.bin_id);
    let p = points(&by_id);
    assert_eq!(p[0], "tiny", "{p:?}");
    assert!(p[1..].iter().all(|&x| x == "sgm-half"), "{p:?}");
    assert_eq!(summary.counters.get("operating/switches"), 1);
    for l in &by_id {
        assert!(l.model_end_ns > l.model_start_ns, "bin {}", l.bin_id);
    }
}
