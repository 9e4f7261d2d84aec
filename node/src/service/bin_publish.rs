//! Each finished bin through the node's outputs: fused into the global map and journaled
//! ([`crate::store::map_store`]), then published once its record is durable, or held until it is
//! ([`super::super::held`]).

use renderer::GaussianSet;

use super::super::error::ServiceError;
use super::super::held::{FusedBin, MAX_HELD_BINS};
use super::Outputs;
use crate::fusion::increment_message;
use crate::msg::gaussians::cloud_from_gaussians;
use crate::msg::pose::pose_from_affine;
use crate::msg::std_msgs::Header;
use crate::msg::tf2_msgs::frame_to;
use crate::msg::Message;
use crate::pipeline::self_check::CheckAction;
use crate::pipeline::worker::{now_ns, Output};
use crate::transport::keys;

impl Outputs<'_> {
    /// Fuses one finished bin and journals it, then publishes it once its record is
    /// durable ([`Outputs::publish_bin`]); until then it is held ([`super::held`]), behind
    /// any bin held before it. Held bins go out first when the journal takes them now.
    pub(super) async fn bin_done(&mut self, out: Output, drops: u64) -> Result<(), ServiceError> {
        self.retry_held(drops).await?;
        if !self.held.has_room() {
            self.counters.add("dropped/not_durable", 1);
            self.closed_ns.remove(&out.bin_id);
            return Ok(());
        }
        if out.result.is_ok() && std::mem::take(&mut self.fused.resume_pending) {
            let header = Header::new(out.stamps.source_ns, &self.world_frame);
            self.put_encoded_update(self.fused.snapshot(header)).await?;
        }
        let bin = self.fuse(out);
        self.held.push(bin);
        if self.fused.failing() {
            if self.held.len() == 1 {
                eprintln!(
                    "the map's journal is not durable: bins are held back from publishing \
                     until it is (at most {MAX_HELD_BINS}; later ones are dropped)"
                );
            }
            self.counters.set("map/held_bins", self.held.len() as u64);
            return Ok(());
        }
        self.publish_held(drops).await
    }

    /// Fuses a bin's map into the global map (a map that failed its check and was not
    /// dimmed is taken in empty: published for what it is, kept out of the map, so the
    /// increments stay one per bin) and journals the change.
    fn fuse(&mut self, mut out: Output) -> FusedBin {
        let Ok(set) = &out.result else {
            return FusedBin {
                out,
                fused: None,
                render: None,
            };
        };
        let unfused = out.check.flagged() && out.check.action != CheckAction::LoweredOpacity;
        let empty = GaussianSet::default();
        let to_fuse = if unfused {
            self.counters.add("check/unfused", 1);
            &empty
        } else {
            set
        };
        let fused = self.fused.fuse(
            out.bin_id,
            to_fuse,
            out.bin_to_world,
            out.stamps.source_ns,
            &mut self.counters,
        );
        out.stamps.map_fused_ns = now_ns();
        FusedBin {
            out,
            fused: Some(fused.map_err(|_| ())),
            render: None,
        }
    }

    /// Publishes the held bins once the journal takes their records (a retry of what
    /// failed); nothing when none is held or the journal still fails.
    pub async fn retry_held(&mut self, drops: u64) -> Result<(), ServiceError> {
        if self.held.is_empty() {
            return Ok(());
        }
        if !self.fused.flush() {
            return Ok(());
        }
        eprintln!(
            "the map's journal is durable again: publishing {} held bins",
            self.held.len()
        );
        self.publish_held(drops).await
    }

    /// Whether everything fused is durable and published (no bin is held): snapshots of
    /// the map may go out.
    pub fn durable(&self) -> bool {
        self.held.is_empty()
    }

    async fn publish_held(&mut self, drops: u64) -> Result<(), ServiceError> {
        for bin in self.held.drain() {
            self.publish_bin(bin, drops).await?;
        }
        self.counters.set("map/held_bins", 0);
        Ok(())
    }

    /// Publishes a fused bin: map, its static transform, pose, map increment (with a
    /// snapshot when due), bird's-eye view, then its latency if the bin has closed and
    /// needs no render, and its render if it came while the bin was held. All stamped with
    /// the bin's source stamp.
    async fn publish_bin(&mut self, bin: FusedBin, drops: u64) -> Result<(), ServiceError> {
        let FusedBin { out, fused, render } = bin;
        let mut stamps = out.stamps;
        let header = |frame: &str| Header::new(stamps.source_ns, frame);
        let world = self.world_frame.clone();
        // Bins are published in bin order: an earlier one not published was dropped.
        let published = &self.published;
        self.closed_ns
            .retain(|id, _| *id >= out.bin_id || published.contains_key(id));
        match &out.result {
            Ok(set) => {
                let frame = format!("bin_{}", out.bin_id);
                match cloud_from_gaussians(set, header(&frame), None) {
                    Ok(cloud) => self.put(keys::BIN_MAP, cloud.encode()).await?,
                    Err(_) => self.counters.add("error/encode_map", 1),
                }
                if let Some(f) = self.foxglove {
                    f.bin_map(out.bin_id, stamps.source_ns, set);
                    f.bin_frame(out.bin_id, &out.bin_to_world, stamps.source_ns);
                }
                let placed = frame_to(&world, frame, &out.bin_to_world, stamps.source_ns);
                self.static_tf.push(placed);
                self.put_static_tf().await?;
                // The pose last: a subscriber holding map and pose has the whole bin.
                let pose = pose_from_affine(&out.bin_to_world, header(&world));
                self.put(keys::BIN_POSE, pose.encode()).await?;
                stamps.publish_ns = now_ns();
                self.summary.bins_published += 1;
                match fused {
                    Some(Ok((inc, sequence))) => {
                        if let Some(f) = self.foxglove {
                            let summary = serde_json::json!({
                                "bin_id": out.bin_id,
                                "sequence": sequence,
                                "added": inc.added.len(),
                                "removed": inc.removed.len(),
                                "total": self.fused.map.total_len(),
                            });
                            let origin = out.bin_to_world.translation;
                            f.map_increment(summary, &inc.added, origin, stamps.source_ns);
                        }
                        let msg = increment_message(&inc, sequence, header(&world));
                        self.put_update(msg).await?;
                        let due = self.snapshot_every > 0
                            && self
                                .summary
                                .bins_published
                                .is_multiple_of(self.snapshot_every);
                        if due {
                            self.put_encoded_update(self.fused.snapshot(header(&world)))
                                .await?;
                        }
                    }
                    _ => self.counters.add("error/fusion", 1),
                }
                if self.bev {
                    self.put_bev(header(&world)).await?;
                }
            }
            Err(_) => self.counters.add("error/reconstruct", 1),
        }
        self.count_check(&out.check);
        if out.render_follows {
            self.awaiting_render.insert(out.bin_id);
        }
        self.published
            .insert(out.bin_id, (stamps, out.check, out.point));
        self.counters.set("queue/depth", out.queue_depth as u64);
        self.flush_latency(drops).await?;
        match render {
            Some(r) => self.rendered(r, drops).await,
            None => Ok(()),
        }
    }
}
