//! Watching a running node: its latency and diagnostics topics, decoded, with the latency
//! percentiles kept up to date ([`LatencyStats`]).

use std::future::Future;

use tokio::sync::mpsc;
use zenoh::Session;

use super::record::zenoh_error;
use crate::msg::latency::{BinLatency, Diagnostics};
use crate::msg::Message;
use crate::service::latency_stats::LatencyStats;
use crate::transport::keys::Keys;
use crate::transport::TransportError;

/// Something the monitor received.
#[derive(Clone, Debug, PartialEq)]
pub enum MonitorEvent {
    /// A bin's latency (already added to the statistics).
    Bin(BinLatency),
    /// The node's counters.
    Diagnostics(Diagnostics),
    /// A payload on the latency or diagnostics key that does not decode (counted).
    Undecodable {
        /// The key it came on.
        key: String,
    },
}

/// What a monitoring session saw.
#[derive(Clone, Debug, Default)]
pub struct MonitorReport {
    /// Every bin's latency received.
    pub stats: LatencyStats,
    /// The last counters received.
    pub diagnostics: Option<Diagnostics>,
    /// Payloads that did not decode.
    pub undecodable: u64,
}

/// Subscribes to the latency and diagnostics topics of `keys` and calls `on_event` with each
/// message (and the statistics so far) until `max_bins` latency messages arrived (`None`:
/// no limit) or `stop` completes.
pub async fn monitor(
    session: &Session,
    keys: &Keys,
    max_bins: Option<u64>,
    stop: impl Future<Output = ()>,
    mut on_event: impl FnMut(&MonitorEvent, &LatencyStats),
) -> Result<MonitorReport, TransportError> {
    let (tx, mut rx) = mpsc::unbounded_channel();
    let mut subscribers = Vec::new();
    for key in [keys.latency(), keys.diagnostics()] {
        let tx = tx.clone();
        let subscriber = session
            .declare_subscriber(key)
            .callback(move |sample| {
                let key = sample.key_expr().to_string();
                // The receiver is gone only after monitoring stopped.
                let _ = tx.send((key, sample.payload().to_bytes().into_owned()));
            })
            .await
            .map_err(zenoh_error)?;
        subscribers.push(subscriber);
    }
    drop(tx);
    let latency_key = keys.latency();
    let mut report = MonitorReport::default();
    let done = |r: &MonitorReport| max_bins.is_some_and(|n| r.stats.bins() >= n);
    tokio::pin!(stop);
    while !done(&report) {
        let (key, payload) = tokio::select! {
            _ = &mut stop => break,
            received = rx.recv() => match received {
                Some(r) => r,
                None => break,
            },
        };
        let event = if key == latency_key {
            BinLatency::decode(&payload).map(MonitorEvent::Bin)
        } else {
            Diagnostics::decode(&payload).map(MonitorEvent::Diagnostics)
        }
        .unwrap_or(MonitorEvent::Undecodable { key });
        match &event {
            MonitorEvent::Bin(latency) => report.stats.push(latency),
            MonitorEvent::Diagnostics(d) => report.diagnostics = Some(d.clone()),
            MonitorEvent::Undecodable { .. } => report.undecodable += 1,
        }
        on_event(&event, &report.stats);
    }
    Ok(report)
}
