//! The live view's zenoh side: subscribes to the node's outputs (map updates, bin poses,
//! renders, bird's-eye views, latency, diagnostics) and to its left input images and camera
//! info, decodes them and updates the [`ViewState`]. A view that starts after the node, or
//! misses an update, asks the node's snapshot queryable for the whole map (at most every
//! two seconds; the node rate-limits it too). Tiles the page asked for that the view has let
//! go are fetched from the same queryable as a region (a box of at most 5 x 5 tiles per
//! query, one query per [`FETCH_EVERY`]).

use std::future::Future;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::DVec2;
use tokio::sync::mpsc;
use zenoh::Session;

use super::state::{rgb_png, MapSync, ViewState};
use zenoh::query::ConsolidationMode;

use crate::fusion::{decode_update, TileKey, Update};
use crate::msg::geometry_msgs::PoseStamped;
use crate::msg::image::{intrinsics_from_camera_info, rgb_from_image};
use crate::msg::latency::{BinLatency, Diagnostics};
use crate::msg::map_update::MapUpdate;
use crate::msg::pose::affine_from_pose;
use crate::msg::sensor_msgs::{CameraInfo, Image};
use crate::msg::Message;
use crate::pipeline::worker::now_ns;
use crate::transport::keys::{self, Keys, Topic};
use crate::transport::TransportError;

/// Least time between two snapshot queries.
const SNAPSHOT_RETRY: Duration = Duration::from_secs(2);

/// Least time between two fetches of let-go tiles.
pub const FETCH_EVERY: Duration = Duration::from_secs(1);
/// Tiles one fetch reaches at most in x and in y from its first tile.
const FETCH_REACH: i64 = 2;

/// Messages waiting to be taken in at most (beyond it they are dropped).
const QUEUE: usize = 256;

/// The topics the view listens to.
const WATCHED: [Topic; 8] = [
    keys::MAP_UPDATE,
    keys::BIN_POSE,
    keys::BIN_RENDER,
    keys::MAP_BEV,
    keys::LATENCY,
    keys::DIAGNOSTICS,
    keys::LEFT_IMAGE,
    keys::LEFT_INFO,
];

/// Feeds `state` from the node's topics under `keys` until `stop` completes.
pub async fn watch(
    session: &Session,
    keys: &Keys,
    state: Arc<Mutex<ViewState>>,
    stop: impl Future<Output = ()>,
) -> Result<(), TransportError> {
    let (tx, mut rx) = mpsc::channel::<(Topic, Vec<u8>)>(QUEUE);
    let mut subscribers = Vec::new();
    for topic in WATCHED {
        let tx = tx.clone();
        let subscriber = session
            .declare_subscriber(keys.key(topic))
            .callback(move |sample| {
                // Full: the message is dropped (a map update's gap then asks for a
                // snapshot); closed: watching stopped.
                let _ = tx.try_send((topic, sample.payload().to_bytes().into_owned()));
            })
            .await
            .map_err(|e| TransportError::Zenoh(e.to_string()))?;
        subscribers.push(subscriber);
    }
    drop(tx);
    let mut last_query: Option<Instant> = None;
    let mut want_snapshot = true;
    let mut fetch = tokio::time::interval(FETCH_EVERY);
    fetch.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    tokio::pin!(stop);
    loop {
        if want_snapshot && last_query.is_none_or(|t| t.elapsed() >= SNAPSHOT_RETRY) {
            last_query = Some(Instant::now());
            want_snapshot = !query_snapshot(session, keys, &state).await;
        }
        let (topic, payload) = tokio::select! {
            _ = &mut stop => break,
            _ = tokio::time::sleep(SNAPSHOT_RETRY), if want_snapshot => continue,
            _ = fetch.tick() => {
                fetch_tiles(session, keys, &state).await;
                continue;
            }
            received = rx.recv() => match received {
                Some(r) => r,
                None => break,
            },
        };
        let mut st = state.lock().unwrap_or_else(|e| e.into_inner());
        if take(&mut st, topic, &payload) == Some(MapSync::NeedsSnapshot) {
            want_snapshot = true;
        }
    }
    Ok(())
}

/// Asks the node for a snapshot and applies it; true when one was applied.
async fn query_snapshot(session: &Session, keys: &Keys, state: &Mutex<ViewState>) -> bool {
    let Ok(replies) = session
        .get(keys.snapshot_request())
        .timeout(Duration::from_secs(2))
        .await
    else {
        return false;
    };
    while let Ok(reply) = replies.recv_async().await {
        let Ok(sample) = reply.result() else {
            continue;
        };
        let payload = sample.payload().to_bytes();
        let paged = sample.attachment().and_then(|a| paged_tiles(&a.to_bytes()));
        let mut st = state.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((side, _)) = &paged {
            st.adopt_tile_side(*side);
        }
        if take(&mut st, keys::MAP_UPDATE, &payload) == Some(MapSync::InSync) {
            if let Some((side, tiles)) = paged {
                st.paged_on_node(side, &tiles);
            }
            return true;
        }
    }
    false
}

/// The tile side and the paged tiles a whole-snapshot reply's attachment names (`None`
/// when it names none or does not parse): the JSON the node's snapshot queryable attaches,
/// `{"tile_m": side, "paged_tiles": [[x, y, gaussians], ...]}`.
pub fn paged_tiles(attachment: &[u8]) -> Option<(f64, Vec<(TileKey, usize)>)> {
    let json: serde_json::Value = serde_json::from_slice(attachment).ok()?;
    let side = json["tile_m"].as_f64()?;
    let tiles = json["paged_tiles"]
        .as_array()?
        .iter()
        .filter_map(|t| {
            let t = t.as_array()?;
            let n = |i: usize| t.get(i).and_then(|v| v.as_i64());
            Some(((n(0)?, n(1)?), usize::try_from(n(2)?).ok()?))
        })
        .collect();
    Some((side, tiles))
}

/// Fetches the first wanted let-go tile, and the wanted ones near it, from the node's
/// region query, and hands what came to the state (nothing when none is wanted; a failed
/// query leaves them wanted for the next try).
async fn fetch_tiles(session: &Session, keys: &Keys, state: &Mutex<ViewState>) {
    let wanted = state
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .wanted_tiles();
    let Some((tiles, parameters)) = fetch_batch(&wanted) else {
        return;
    };
    let selector = format!("{}?{parameters}", keys.snapshot_request());
    // The pages share one key: consolidation would keep only the last.
    let Ok(replies) = session
        .get(selector)
        .consolidation(ConsolidationMode::None)
        .timeout(Duration::from_secs(5))
        .await
    else {
        return;
    };
    let mut gaussians = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        let Ok(sample) = reply.result() else {
            return;
        };
        let page = MapUpdate::decode(&sample.payload().to_bytes())
            .ok()
            .and_then(|m| decode_update(&m).ok());
        match page {
            Some(Update::Snapshot(s)) => gaussians.extend(s.gaussians),
            _ => return,
        }
    }
    state
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .tiles_fetched(&tiles, &gaussians);
}

/// What one fetch asks the node for: the first of the `wanted` let-go tiles (with their
/// ground boxes, [`ViewState::wanted_tiles`]) and the others within `FETCH_REACH` tiles of
/// it, and the region query's parameters for the box around them (`box=x0,y0,x1,y1`,
/// [`crate::service::region`]); `None` when none is wanted.
pub fn fetch_batch(wanted: &[(TileKey, (DVec2, DVec2))]) -> Option<(Vec<TileKey>, String)> {
    let &(first, _) = wanted.first()?;
    let reach = FETCH_REACH.unsigned_abs();
    let batch: Vec<_> = wanted
        .iter()
        .filter(|(k, _)| k.0.abs_diff(first.0) <= reach && k.1.abs_diff(first.1) <= reach)
        .collect();
    let lo = batch
        .iter()
        .map(|(_, b)| b.0)
        .reduce(|a, b| a.min(b))
        .unwrap_or_default();
    let hi = batch
        .iter()
        .map(|(_, b)| b.1)
        .reduce(|a, b| a.max(b))
        .unwrap_or_default();
    let tiles = batch.iter().map(|(k, _)| *k).collect();
    Some((tiles, format!("box={},{},{},{}", lo.x, lo.y, hi.x, hi.y)))
}

/// Takes `payload` in as one message of the `n`-th topic the view watches (modulo their
/// number: map update, bin pose, bin render, bird's-eye view, latency, diagnostics, left
/// image, left camera info), as the watcher takes each sample: what the fuzzing of the
/// view's topics calls (`crate::untrusted_input::live::view_topics`). Returns how the map
/// fared for a map update.
pub fn take_sample(st: &mut ViewState, n: usize, payload: &[u8]) -> Option<MapSync> {
    take(st, WATCHED[n % WATCHED.len()], payload)
}

/// Decodes one message of `topic` into the state. Returns how the map fared for map
/// updates, `None` for other topics. A message that does not decode is counted.
fn take(st: &mut ViewState, topic: Topic, payload: &[u8]) -> Option<MapSync> {
    let ok = match topic {
        t if t == keys::MAP_UPDATE => {
            let update = MapUpdate::decode(payload)
                .ok()
                .and_then(|m| Some((m.sequence, decode_update(&m).ok()?)));
            match update {
                Some((sequence, update)) => return Some(st.map_update(sequence, update)),
                None => false,
            }
        }
        t if t == keys::BIN_POSE => PoseStamped::decode(payload)
            .ok()
            .and_then(|m| Some((m.header.stamp.to_nanos(), affine_from_pose(&m).ok()?)))
            .map(|(stamp, pose)| st.bin_pose(stamp, pose))
            .is_some(),
        t if t == keys::BIN_RENDER => Image::decode(payload)
            .ok()
            .and_then(|m| {
                let bin_id = bin_of(&m.header.frame_id)?;
                let rgb = rgb_from_image(&m).ok()?;
                let png = rgb_png(rgb.width, rgb.height, rgb.to_rgb8())?;
                Some((bin_id, m.header.stamp.to_nanos(), png))
            })
            .map(|(bin_id, stamp, png)| st.render(bin_id, stamp, png))
            .is_some(),
        t if t == keys::MAP_BEV => Image::decode(payload)
            .ok()
            .and_then(|m| {
                let rgb = rgb_from_image(&m).ok()?;
                rgb_png(rgb.width, rgb.height, rgb.to_rgb8())
            })
            .map(|png| st.bev(png))
            .is_some(),
        t if t == keys::LATENCY => BinLatency::decode(payload).map(|l| st.latency(l)).is_ok(),
        t if t == keys::DIAGNOSTICS => Diagnostics::decode(payload)
            .map(|d| st.diagnostics(&d))
            .is_ok(),
        t if t == keys::LEFT_IMAGE => Image::decode(payload)
            .map(|m| st.input_image(now_ns(), m))
            .is_ok(),
        t if t == keys::LEFT_INFO => CameraInfo::decode(payload)
            .ok()
            .and_then(|m| intrinsics_from_camera_info(&m).ok())
            .map(|(k, _)| st.intrinsics(k))
            .is_some(),
        _ => true,
    };
    if !ok {
        st.undecodable();
    }
    None
}

/// The bin id in a `bin_<id>` frame name.
fn bin_of(frame_id: &str) -> Option<u64> {
    frame_id.strip_prefix("bin_")?.parse().ok()
}
