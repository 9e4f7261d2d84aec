//! Everything the node sends, and the state behind it: per finished bin its map, pose, the
//! global map's increment (and a snapshot every N bins or on request) and bird's-eye view,
//! then its render when the worker has drawn it, and the bin's latency once the bin has
//! also closed, with the counters beside it.
//!
//! Write-ahead: a bin is fused and its change journaled and synced (when due,
//! [`crate::store::map_store`]) before anything of the bin is published, so a crash cannot lose a
//! published bin. When the journal fails (a full disk), bins are held back until it takes
//! them again ([`super::held`]), snapshot queries are refused meanwhile, and the
//! counters say so (`error/checkpoint`, `map/held_bins`, `dropped/not_durable`). A resumed
//! map says so: its
//! first `map/update` is a snapshot of the restored map with the restored sequence number
//! (a new map's first is increment 1), and the increments go on from there; the counter
//! `map/epoch` in the diagnostics is the number of times the map was resumed.
//!
//! Derived data keeps its source's stamp: a bin's map, pose, render, map update and
//! bird's-eye view carry the `header.stamp` of the bin's first frame (the node's own times
//! go out in the latency message). Transforms for ROS tools: `/tf_static` holds world ->
//! `bin_<id>` for every bin so far (the whole set in each message, as tf2's static
//! broadcaster sends it, again with every bin and every diagnostics period so late joiners
//! get it), `/tf` world -> the left camera per frame.
//!
//! Every map's self-check goes out in the bin's latency message and is counted:
//! `check/pass`, `check/fail`, `check/undetermined`, and what was done about failures,
//! `check/flagged`, `check/lowered_opacity`, `check/fallback_sgm` (with
//! `check/fallback_sgm_failed` when SGM's map failed too).
//!
//! With a Foxglove server ([`crate::foxglove`]) the same outputs go to it too, handed over
//! without blocking: the bin map, its frame, the fused map's new points, the render, the
//! camera, the latency and the counters (with the server's own).
//!
//! The map fused into, its store and what is read from it are [`super::fused_map`]; this
//! module publishes.

use glam::DVec2;
use std::collections::{BTreeMap, BTreeSet};

use super::error::ServiceError;
use super::held::Held;
use super::inputs::CameraPose;
use super::static_frames::StaticFrames;
use crate::counters::Counters;
use crate::foxglove::messages::latency_json;
use crate::foxglove::Foxglove;
use crate::fusion::{bev_image, BevView, GlobalMap};
use crate::memory::Releaser;
use crate::msg::image::image_from_rgb;
use crate::msg::latency::{BinLatency, Diagnostics};
use crate::msg::map_update::MapUpdate;
use crate::msg::sensor_msgs::Image;
use crate::msg::std_msgs::Header;
use crate::msg::tf2_msgs::{frame_to, TfMessage, WORLD};
use crate::msg::Message;
use crate::pipeline::self_check::{verdict_code, CheckAction, CheckOutcome};
use crate::pipeline::worker::{now_ns, Rendered, Stamps, WorkerEvent};
use crate::store::map_store::MapStore;
use crate::transport::keys::{self, Topic};
use crate::transport::Outlet;

#[path = "bin_publish.rs"]
mod bin_publish;

pub(super) use super::fused_map::FusedMap;

/// What a run of the node did.
#[derive(Clone, Debug, Default)]
pub struct NodeSummary {
    /// Bins whose maps were published.
    pub bins_published: u64,
    /// Gaussians in the global map at the end (in memory and in tiles paged out).
    pub global_gaussians: usize,
    /// The counters at the end.
    pub counters: Counters,
}

/// The bird's-eye view published per bin: 256 x 256 pixels at 0.25 m, 64 m square around
/// the latest bin's origin.
const BEV: (u32, f64) = (256, 0.25);

/// The node's outputs and the state they are made from.
pub(super) struct Outputs<'a> {
    outlet: &'a Outlet,
    /// The Foxglove server, when the node runs one.
    foxglove: Option<&'a Foxglove>,
    /// The fused global map and what keeps it on disk.
    pub fused: FusedMap,
    /// Publish the bird's-eye view per bin.
    bev: bool,
    /// Snapshot period in bins (0: on request only).
    snapshot_every: u64,
    /// Bins fused whose journal record is not yet durable, not yet published.
    held: Held,
    /// Stamps of closed bins, until their map is published.
    closed_ns: BTreeMap<u64, i64>,
    /// Stamps, self-check and operating point of published bins, until they close (and
    /// their render is out).
    published: BTreeMap<u64, (Stamps, CheckOutcome, usize)>,
    /// The worker's operating points' names, by index (the latency message's
    /// `operating_point`).
    point_names: Vec<String>,
    /// Published bins whose render is still to come.
    awaiting_render: BTreeSet<u64>,
    /// World -> `bin_<id>` of the most recent bins published, what `/tf_static` carries.
    static_tf: StaticFrames,
    /// The frame the map, the bin poses and the transforms are in (the poses' frame).
    world_frame: String,
    /// Bad input, drops, errors.
    pub counters: Counters,
    /// What the run did.
    pub summary: NodeSummary,
}

impl<'a> Outputs<'a> {
    /// Nothing published yet; bins are fused into `map` (new or resumed); `bev` switches the
    /// per-bin bird's-eye view on.
    pub fn new(
        outlet: &'a Outlet,
        map: GlobalMap,
        bev: bool,
        snapshot_every: u64,
        store: Option<MapStore>,
    ) -> Self {
        let mut counters = Counters::default();
        counters.set("map/epoch", map.epoch());
        Self {
            outlet,
            foxglove: None,
            fused: FusedMap::new(map, store),
            bev,
            snapshot_every,
            held: Held::default(),
            closed_ns: BTreeMap::new(),
            published: BTreeMap::new(),
            point_names: Vec::new(),
            awaiting_render: BTreeSet::new(),
            static_tf: StaticFrames::default(),
            world_frame: WORLD.into(),
            counters,
            summary: NodeSummary::default(),
        }
    }

    /// Names the worker's operating points, by index.
    pub fn with_points(mut self, names: Vec<String>) -> Self {
        self.point_names = names;
        self
    }

    /// Keeps `releaser` running while the node does, its counters among the node's.
    pub fn with_releaser(mut self, releaser: Option<Releaser>) -> Self {
        self.fused.releaser = releaser;
        self
    }

    /// Publishes in `frame` (the poses' frame) instead of [`WORLD`].
    pub fn with_world_frame(mut self, frame: &str) -> Self {
        self.world_frame = frame.into();
        self
    }

    /// Sends the outputs to `foxglove` as well.
    pub fn with_foxglove(mut self, foxglove: Option<&'a Foxglove>) -> Self {
        self.foxglove = foxglove;
        self
    }

    /// The map was resumed: publish its snapshot before the first increment.
    pub fn announce_resume(&mut self) {
        self.fused.resume_pending = true;
    }

    /// Publishes what the worker handed back.
    pub async fn worker_event(&mut self, e: WorkerEvent, drops: u64) -> Result<(), ServiceError> {
        match e {
            WorkerEvent::Map(out) => self.bin_done(*out, drops).await,
            WorkerEvent::Render(r) => self.rendered(r, drops).await,
        }
    }

    /// Counts a bin's self-check and what was done about it.
    fn count_check(&mut self, check: &CheckOutcome) {
        if let Some(r) = &check.primary {
            self.counters.add(&format!("check/{}", r.verdict.name()), 1);
        }
        let action = match check.action {
            CheckAction::None => return,
            CheckAction::Flagged => "check/flagged",
            CheckAction::LoweredOpacity => "check/lowered_opacity",
            CheckAction::Sgm => "check/fallback_sgm",
        };
        self.counters.add(action, 1);
        if check.action == CheckAction::Sgm && check.flagged() {
            self.counters.add("check/fallback_sgm_failed", 1);
        }
    }

    /// Publishes a bin's render (frame `bin_<id>`, stamped like its map) and then its
    /// latency if the bin has closed.
    async fn rendered(&mut self, r: Rendered, drops: u64) -> Result<(), ServiceError> {
        let Some(r) = self.held.take_render(r) else {
            return Ok(());
        };
        self.awaiting_render.remove(&r.bin_id);
        let stamps = self.published.get_mut(&r.bin_id).map(|(s, _, _)| s);
        let source_ns = stamps.as_ref().map_or(0, |s| s.source_ns);
        if let Some(s) = stamps {
            s.render_end_ns = r.render_end_ns;
        }
        match r.image {
            Ok(img) => {
                if let Some(f) = self.foxglove {
                    f.render(r.bin_id, source_ns, &img);
                }
                let header = Header::new(source_ns, format!("bin_{}", r.bin_id));
                let msg = image_from_rgb(&img, header);
                self.put(keys::BIN_RENDER, msg.encode()).await?;
            }
            Err(_) => self.counters.add("error/render", 1),
        }
        self.flush_latency(drops).await
    }

    /// Notes that `bin_id` closed (its last frame arrived) and publishes what is ready.
    pub async fn bin_closed(&mut self, bin_id: u64, drops: u64) -> Result<(), ServiceError> {
        self.closed_ns.insert(bin_id, now_ns());
        self.flush_latency(drops).await
    }

    /// At the end of a run: publishes the latency of every published bin still waiting for
    /// its close or its render. The drive's last bin never closes (no frame after it), so
    /// its message has no close stamp (`bin_close_ns` 0) and no before-close margin.
    pub async fn finish(&mut self, drops: u64) -> Result<(), ServiceError> {
        self.retry_held(drops).await?;
        let held = self.held.drain().len();
        if held > 0 {
            eprintln!(
                "{held} bins were never published: the map's journal refused their records \
                 to the end (the map saved at the stop holds them if it can be written)"
            );
            self.counters.add("dropped/not_durable", held as u64);
        }
        self.awaiting_render.clear();
        let open: Vec<u64> = self.published.keys().copied().collect();
        for id in open {
            self.closed_ns.entry(id).or_insert(0);
        }
        self.flush_latency(drops).await
    }

    /// The header of a snapshot answering a query: the world frame at the latest fused
    /// bin's source stamp (0 before any).
    pub fn snapshot_header(&self) -> Header {
        Header::new(self.fused.latest_source_ns, &self.world_frame)
    }

    /// Publishes world -> the left camera of a frame that entered the binner on `/tf`, when
    /// `on_tf` (not when the camera's pose came from the `/tf` tree itself: its frame has a
    /// parent there already), and to Foxglove.
    pub async fn camera_moved(
        &mut self,
        camera: CameraPose,
        on_tf: bool,
    ) -> Result<(), ServiceError> {
        if let Some(f) = self.foxglove {
            f.camera(&camera.frame_id, &camera.left_to_world, camera.stamp_ns);
        }
        if !on_tf {
            return Ok(());
        }
        let msg = TfMessage {
            transforms: vec![frame_to(
                &self.world_frame,
                camera.frame_id,
                &camera.left_to_world,
                camera.stamp_ns,
            )],
        };
        self.put(keys::TF, msg.encode()).await
    }

    /// Publishes the static transforms of the most recent bins on `/tf_static` (nothing
    /// before the first bin; [`StaticFrames`] says which and why), so a subscriber that
    /// joined late can place every bin it will receive.
    pub async fn put_static_tf(&mut self) -> Result<(), ServiceError> {
        if self.static_tf.is_empty() {
            return Ok(());
        }
        let msg = TfMessage {
            transforms: self.static_tf.to_vec(),
        };
        self.put(keys::TF_STATIC, msg.encode()).await
    }

    async fn put_update(
        &mut self,
        msg: Result<MapUpdate, crate::msg::ConvertError>,
    ) -> Result<(), ServiceError> {
        self.put_encoded_update(msg.map(|m| m.encode())).await
    }

    /// Publishes an encoded MapUpdate; one that could not be encoded is counted.
    async fn put_encoded_update(
        &mut self,
        payload: Result<Vec<u8>, crate::msg::ConvertError>,
    ) -> Result<(), ServiceError> {
        match payload {
            Ok(bytes) => self.put(keys::MAP_UPDATE, bytes).await,
            Err(_) => {
                self.counters.add("error/encode_map_update", 1);
                Ok(())
            }
        }
    }

    async fn put_bev(&mut self, header: Header) -> Result<(), ServiceError> {
        let Some(origin) = self.fused.map.latest_origin() else {
            return Ok(());
        };
        let view = BevView::square(DVec2::new(origin.x, origin.y), BEV.0, BEV.1);
        // Only the Gaussians near the view: the cost follows the view, not the map.
        let (min, max) = view.ground_box();
        let near = self.fused.map.gaussians_in(min, max);
        match bev_image(near.into_iter().map(|(_, g)| g), &view) {
            Ok(img) => {
                let msg = Image {
                    header,
                    height: img.height(),
                    width: img.width(),
                    encoding: "rgb8".into(),
                    is_bigendian: 0,
                    step: 3 * img.width(),
                    data: img.into_raw(),
                };
                self.put(keys::MAP_BEV, msg.encode()).await
            }
            Err(_) => {
                self.counters.add("error/bev", 1);
                Ok(())
            }
        }
    }

    /// Publishes the latency of every bin that is closed, published and rendered (when a
    /// render was due), and the counters.
    async fn flush_latency(&mut self, drops: u64) -> Result<(), ServiceError> {
        let ready: Vec<u64> = self
            .published
            .keys()
            .filter(|id| self.closed_ns.contains_key(id) && !self.awaiting_render.contains(id))
            .copied()
            .collect();
        for id in ready {
            let (s, check, point) = self.published.remove(&id).unwrap_or_default();
            let score = |r: Option<&model::consistency::CheckReport>| r.map_or(0.0, |r| r.score);
            let closed = self.closed_ns.remove(&id).unwrap_or_default();
            let msg = BinLatency {
                bin_id: id,
                first_frame_arrival_ns: s.arrival_ns,
                bin_close_ns: closed,
                model_start_ns: s.model_start_ns,
                model_end_ns: s.model_end_ns,
                render_end_ns: s.render_end_ns,
                publish_ns: s.publish_ns,
                queue_depth: self.counters.get("queue/depth") as u32,
                drops,
                bad_messages: self.counters.sum("bad_message/"),
                check_verdict: verdict_code(check.primary.as_ref()),
                check_action: check.action.code(),
                fallback_verdict: verdict_code(check.fallback.as_ref()),
                check_samples: check.primary.map_or(0, |r| r.samples),
                check_score: score(check.primary.as_ref()) as f64,
                fallback_score: score(check.fallback.as_ref()) as f64,
                base_end_ns: s.stage_end_ns[0],
                pseudo_render_end_ns: s.stage_end_ns[1],
                enhance_end_ns: s.stage_end_ns[2],
                plus_end_ns: s.stage_end_ns[3],
                fuse_end_ns: s.stage_end_ns[4],
                map_fused_ns: s.map_fused_ns,
                operating_point: self.point_names.get(point).cloned().unwrap_or_default(),
            };
            self.put(keys::LATENCY, msg.encode()).await?;
            if let Some(f) = self.foxglove {
                f.latency(latency_json(&msg));
            }
            let diagnostics = self.diagnostics();
            self.put(keys::DIAGNOSTICS, diagnostics.encode()).await?;
        }
        Ok(())
    }

    /// The counters as a Diagnostics message stamped now, with the Foxglove server's own
    /// counters taken in first and the counters sent to it too.
    pub fn diagnostics(&mut self) -> Diagnostics {
        let now = now_ns();
        self.fused.releaser_counts_into(&mut self.counters);
        if let Some(f) = self.foxglove {
            f.count_into(&mut self.counters);
            f.counters(&self.counters, now);
        }
        self.counters.diagnostics(now)
    }

    async fn put(&self, topic: Topic, payload: Vec<u8>) -> Result<(), ServiceError> {
        Ok(self.outlet.put(topic, payload).await?)
    }
}
