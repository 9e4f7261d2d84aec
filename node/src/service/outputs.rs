//! Everything the node sends, and the state behind it: per finished bin its map, pose, the
//! global map's increment (and a snapshot every N bins or on request) and bird's-eye view,
//! then its render when the worker has drawn it, and the bin's latency once the bin has
//! also closed, with the counters beside it.

use std::collections::{BTreeMap, BTreeSet};

use glam::DVec2;

use super::counters::Counters;
use super::keys::{self, Topic};
use super::node::{NodeSummary, ServiceError};
use crate::fusion::{
    bev_image, increment_message, snapshot_message, BevView, FusionConfig, GlobalMap,
};
use crate::msg::gaussians::cloud_from_gaussians;
use crate::msg::image::image_from_rgb;
use crate::msg::latency::BinLatency;
use crate::msg::map_update::MapUpdate;
use crate::msg::pose::pose_from_affine;
use crate::msg::sensor_msgs::Image;
use crate::msg::std_msgs::Header;
use crate::msg::Message;
use crate::pipeline::worker::{now_ns, Output, Rendered, Stamps, WorkerEvent};
use crate::transport::Outlet;

/// The bird's-eye view published per bin: 256 x 256 pixels at 0.25 m, 64 m square around
/// the latest bin's origin.
const BEV: (u32, f64) = (256, 0.25);

/// The node's outputs and the state they are made from.
pub(super) struct Outputs<'a> {
    outlet: &'a Outlet,
    /// The fused global map.
    pub map: GlobalMap,
    /// Publish the bird's-eye view per bin.
    bev: bool,
    /// Snapshot period in bins (0: on request only).
    snapshot_every: u64,
    /// Sequence number of the last increment published.
    sequence: u64,
    /// Stamps of closed bins, until their map is published.
    closed_ns: BTreeMap<u64, i64>,
    /// Stamps of published bins, until they close (and their render is out).
    published: BTreeMap<u64, Stamps>,
    /// Published bins whose render is still to come.
    awaiting_render: BTreeSet<u64>,
    /// Bad input, drops, errors.
    pub counters: Counters,
    /// What the run did.
    pub summary: NodeSummary,
}

impl<'a> Outputs<'a> {
    /// Nothing published yet; `bev` switches the per-bin bird's-eye view on.
    pub fn new(
        outlet: &'a Outlet,
        fusion: FusionConfig,
        bev: bool,
        snapshot_every: u64,
    ) -> Result<Self, ServiceError> {
        Ok(Self {
            outlet,
            map: GlobalMap::new(fusion)?,
            bev,
            snapshot_every,
            sequence: 0,
            closed_ns: BTreeMap::new(),
            published: BTreeMap::new(),
            awaiting_render: BTreeSet::new(),
            counters: Counters::default(),
            summary: NodeSummary::default(),
        })
    }

    /// Publishes what the worker handed back.
    pub async fn worker_event(&mut self, e: WorkerEvent, drops: u64) -> Result<(), ServiceError> {
        match e {
            WorkerEvent::Map(out) => self.bin_done(*out, drops).await,
            WorkerEvent::Render(r) => self.rendered(r, drops).await,
        }
    }

    /// Publishes one finished bin: map, pose, map increment (and a snapshot when due),
    /// bird's-eye view, then its latency if the bin has closed and needs no render.
    async fn bin_done(&mut self, out: Output, drops: u64) -> Result<(), ServiceError> {
        let mut stamps = out.stamps;
        let header = |frame: &str| Header::new(stamps.arrival_ns, frame);
        match out.result {
            Ok(set) => {
                let frame = format!("bin_{}", out.bin_id);
                match cloud_from_gaussians(&set, header(&frame), None) {
                    Ok(cloud) => self.put(keys::BIN_MAP, cloud.encode()).await?,
                    Err(_) => self.counters.add("error/encode_map", 1),
                }
                // The pose last: a subscriber holding map and pose has the whole bin.
                let pose = pose_from_affine(&out.bin_to_world, header("world"));
                self.put(keys::BIN_POSE, pose.encode()).await?;
                stamps.publish_ns = now_ns();
                self.summary.bins_published += 1;
                match self.map.insert_bin(out.bin_id, &set, out.bin_to_world) {
                    Ok(inc) => {
                        self.sequence += 1;
                        let msg = increment_message(&inc, self.sequence, header("world"));
                        self.put_update(msg).await?;
                        let due = self.snapshot_every > 0
                            && self
                                .summary
                                .bins_published
                                .is_multiple_of(self.snapshot_every);
                        if due {
                            self.put_update(self.snapshot(header("world"))).await?;
                        }
                    }
                    Err(_) => self.counters.add("error/fusion", 1),
                }
                if self.bev {
                    self.put_bev(header("world")).await?;
                }
            }
            Err(_) => self.counters.add("error/reconstruct", 1),
        }
        if out.render_follows {
            self.awaiting_render.insert(out.bin_id);
        }
        self.published.insert(out.bin_id, stamps);
        self.counters.set("queue/depth", out.queue_depth as u64);
        self.flush_latency(drops).await
    }

    /// Publishes a bin's render (frame `bin_<id>`, stamped like its map) and then its
    /// latency if the bin has closed.
    async fn rendered(&mut self, r: Rendered, drops: u64) -> Result<(), ServiceError> {
        self.awaiting_render.remove(&r.bin_id);
        let stamps = self.published.get_mut(&r.bin_id);
        let arrival_ns = stamps.as_ref().map_or(0, |s| s.arrival_ns);
        if let Some(s) = stamps {
            s.render_end_ns = r.render_end_ns;
        }
        match r.image {
            Ok(img) => {
                let header = Header::new(arrival_ns, format!("bin_{}", r.bin_id));
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

    /// The whole map as a MapUpdate snapshot at the current sequence number.
    pub fn snapshot(&self, header: Header) -> Result<MapUpdate, crate::msg::ConvertError> {
        snapshot_message(&self.map.snapshot(), self.sequence, header)
    }

    async fn put_update(
        &mut self,
        msg: Result<MapUpdate, crate::msg::ConvertError>,
    ) -> Result<(), ServiceError> {
        match msg {
            Ok(m) => self.put(keys::MAP_UPDATE, m.encode()).await,
            Err(_) => {
                self.counters.add("error/encode_map_update", 1);
                Ok(())
            }
        }
    }

    async fn put_bev(&mut self, header: Header) -> Result<(), ServiceError> {
        let Some(origin) = self.map.latest_origin() else {
            return Ok(());
        };
        let view = BevView {
            centre: DVec2::new(origin.x, origin.y),
            width: BEV.0,
            height: BEV.0,
            metres_per_pixel: BEV.1,
            background: [0, 0, 0],
        };
        match bev_image(self.map.gaussians().map(|(_, g)| g), &view) {
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
            let s = self.published.remove(&id).unwrap_or_default();
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
            };
            self.put(keys::LATENCY, msg.encode()).await?;
            let diagnostics = self.counters.diagnostics(now_ns());
            self.put(keys::DIAGNOSTICS, diagnostics.encode()).await?;
        }
        Ok(())
    }

    async fn put(&self, topic: Topic, payload: Vec<u8>) -> Result<(), ServiceError> {
        Ok(self.outlet.put(topic, payload).await?)
    }
}
