//! `stereosplat monitor`: the node's per-bin latency live, with percentiles.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

use super::common::shutdown::shutdown_signal;
use super::common::zenoh_args::ZenohArgs;
use super::record::create_parent;
use crate::clients::{self, MonitorEvent};
use crate::msg::latency::BinLatency;
use crate::service::latency_stats::bin_stages_ms;
use crate::service::LatencyStats;
use crate::transport::open;

/// Flags of `monitor`.
#[derive(Args, Clone, Debug)]
pub struct MonitorArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// Stop after this many bins (default: at Ctrl-C or SIGTERM).
    #[arg(long)]
    bins: Option<u64>,
    /// Print the percentile table every this many bins (0: only at the end).
    #[arg(long, default_value_t = 10)]
    table_every: u64,
    /// Write the final latency summary here as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Prints a line per bin and the percentile table every few bins and at the end.
pub fn monitor(args: &MonitorArgs) -> Result<()> {
    let keys = args.zenoh.keys();
    let runtime = tokio::runtime::Runtime::new()?;
    let report = runtime.block_on(async {
        let session = open(&args.zenoh.transport()).await?;
        eprintln!("monitor ready: {}", keys.latency());
        let on_event = |event: &MonitorEvent, stats: &LatencyStats| match event {
            MonitorEvent::Bin(latency) => {
                println!("{}", bin_line(latency));
                if args.table_every > 0 && stats.bins().is_multiple_of(args.table_every) {
                    println!("{}", stats.summary());
                }
            }
            MonitorEvent::Diagnostics(_) => {}
            MonitorEvent::Undecodable { key } => eprintln!("undecodable message on {key}"),
        };
        let watched = clients::monitor(&session, &keys, args.bins, shutdown_signal(), on_event);
        anyhow::Ok(watched.await?)
    })?;
    let summary = report.stats.summary();
    println!("{summary}");
    if let Some(d) = &report.diagnostics {
        let counters: Vec<String> = d
            .counters
            .iter()
            .map(|c| format!("{} {}", c.kind, c.count))
            .collect();
        println!("counters: {}", counters.join(", "));
    }
    if let Some(path) = &args.json {
        create_parent(path)?;
        let text = serde_json::to_string_pretty(&summary)?;
        std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// One line for a bin: its stage latencies in ms (`-` where a stamp is missing), queue,
/// counters and self-check (verdict, score, and what was done about a failure).
fn bin_line(l: &BinLatency) -> String {
    let verdict = |code: u8| match code {
        1 => "pass",
        2 => "FAIL",
        3 => "undetermined",
        _ => "not run",
    };
    let mut check = format!("check {} {:.2}", verdict(l.check_verdict), l.check_score);
    match l.check_action {
        1 => check.push_str(" (published flagged)"),
        2 => check.push_str(" (opacity lowered)"),
        3 => check.push_str(&format!(
            " -> sgm {} {:.2}",
            verdict(l.fallback_verdict),
            l.fallback_score
        )),
        _ => {}
    }
    let stages: Vec<String> = bin_stages_ms(l)
        .iter()
        .map(|(name, ms)| match ms {
            Some(ms) => format!("{name} {ms:.1}"),
            None => format!("{name} -"),
        })
        .collect();
    let point = match l.operating_point.as_str() {
        "" => String::new(),
        p => format!("point {p}; "),
    };
    format!(
        "bin {:>4}: {point}{} ms; queue {}, drops {}, bad {}; {check}",
        l.bin_id,
        stages.join(", "),
        l.queue_depth,
        l.drops,
        l.bad_messages
    )
}
