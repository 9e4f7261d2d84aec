//! What the live view knows about the node, rebuilt from its topics: a tiled copy of the
//! global map near the vehicle ([`ViewTiles`]; the page's splat viewer loads it tile by
//! tile, and the whole held copy as one PLY, cached per map version), the
//! latest bin's render, input image and bird's-eye view as PNG, every bin's camera, and a
//! bounded history of per-bin latencies and the counters. Memory is bounded: histories are
//! capped in entries and the held input images in bytes.

use std::collections::VecDeque;
use std::sync::Arc;

use glam::{DAffine3, DVec2, DVec3};
use renderer::Intrinsics;
use serde_json::{json, Value};

use super::tiles::{most_opaque, TileRules, ViewTiles};
use crate::fusion::{local_set, GaussianId, TileKey, Update, WorldGaussian};
use crate::msg::latency::{BinLatency, Diagnostics};
use crate::msg::sensor_msgs::Image;
use crate::service::latency_stats::bin_stages_ms;

/// Latency rows kept for the charts (the oldest go first).
pub const MAX_LATENCY_ROWS: usize = 512;
/// Bin cameras kept.
const MAX_BINS: usize = 512;
/// Bytes of left input images held to find each bin's input (the oldest go first).
const MAX_INPUT_BYTES: usize = 64 << 20;

/// A PNG picture of one bin.
#[derive(Clone, Debug)]
pub struct Picture {
    /// The bin it shows (for the bird's-eye view: the latest bin when it was drawn).
    pub bin_id: u64,
    /// The encoded PNG.
    pub png: Arc<Vec<u8>>,
}

/// What the map copy said about an update it was handed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapSync {
    /// Applied (or already included).
    InSync,
    /// The update does not follow what the copy holds: a snapshot is needed.
    NeedsSnapshot,
}

/// The view's state; one lock guards it and every access is short.
#[derive(Debug, Default)]
pub struct ViewState {
    tiles: ViewTiles,
    /// Sequence number of the last update the copy includes (`None`: nothing yet).
    sequence: Option<u64>,
    /// Bumped on every change of the copy.
    map_version: u64,
    /// World point the served PLY is relative to (fixed once set, so the page's camera
    /// does not jump as the map grows).
    origin: Option<DVec3>,
    ply_cache: Option<(u64, Arc<Vec<u8>>)>,
    /// Bin poses with their header stamp (the bin's first-frame arrival on the node's
    /// clock, which its latency message names too).
    bins: VecDeque<(i64, DAffine3)>,
    latency: VecDeque<BinLatency>,
    bins_seen: u64,
    counters: Vec<(String, u64)>,
    intrinsics: Option<Intrinsics>,
    /// Left images as received, with the view's receive time (ns, the node's latency clock).
    inputs: VecDeque<(i64, Image)>,
    input_bytes: usize,
    render: Option<Picture>,
    input: Option<Picture>,
    bev: Option<Picture>,
    undecodable: u64,
}

impl ViewState {
    /// Takes a map update in: a snapshot replaces the copy, an increment applies when it
    /// is the next in sequence (an older one is already included and skipped).
    pub fn map_update(&mut self, sequence: u64, update: Update) -> MapSync {
        match update {
            Update::Snapshot(snapshot) => {
                if self.sequence.is_some_and(|s| s > sequence) {
                    return MapSync::InSync;
                }
                self.tiles.replace(&snapshot, self.map_version + 1);
                self.sequence = Some(sequence);
                self.set_origin_from_map();
            }
            Update::Increment(inc) => match self.sequence {
                Some(s) if sequence <= s => return MapSync::InSync,
                Some(s) if sequence == s + 1 => {
                    if self.tiles.apply(&inc, self.map_version + 1).is_err() {
                        return MapSync::NeedsSnapshot;
                    }
                    self.sequence = Some(sequence);
                    self.set_origin_from_map();
                }
                // The first increment of a map the view saw from its start.
                None if sequence == 1 => {
                    if self.tiles.apply(&inc, self.map_version + 1).is_err() {
                        return MapSync::NeedsSnapshot;
                    }
                    self.sequence = Some(sequence);
                    self.set_origin_from_map();
                }
                _ => return MapSync::NeedsSnapshot,
            },
        }
        self.map_version += 1;
        MapSync::InSync
    }

    fn set_origin_from_map(&mut self) {
        if self.origin.is_none() {
            self.origin = self.tiles.gaussians().next().map(|g| g.position);
        }
    }

    /// A bin's pose (bin frame, which is its input camera's frame, to world) with its
    /// header stamp.
    pub fn bin_pose(&mut self, stamp_ns: i64, bin_to_world: DAffine3) {
        self.origin.get_or_insert(bin_to_world.translation);
        if self.bins.len() == MAX_BINS {
            self.bins.pop_front();
        }
        self.bins.push_back((stamp_ns, bin_to_world));
        let before = self.tiles.tile_counts();
        self.tiles.let_go_far_from(bin_to_world.translation);
        if self.tiles.tile_counts() != before {
            self.map_version += 1;
        }
    }

    /// A bin's latency message.
    pub fn latency(&mut self, latency: BinLatency) {
        if self.latency.len() == MAX_LATENCY_ROWS {
            self.latency.pop_front();
        }
        self.latency.push_back(latency);
        self.bins_seen += 1;
    }

    /// The node's counters.
    pub fn diagnostics(&mut self, d: &Diagnostics) {
        self.counters = d
            .counters
            .iter()
            .map(|c| (c.kind.clone(), c.count))
            .collect();
    }

    /// The left camera's intrinsics.
    pub fn intrinsics(&mut self, k: Intrinsics) {
        self.intrinsics = Some(k);
    }

    /// A left input image, received at `received_ns`.
    pub fn input_image(&mut self, received_ns: i64, image: Image) {
        self.input_bytes += image.data.len();
        self.inputs.push_back((received_ns, image));
        while self.input_bytes > MAX_INPUT_BYTES {
            match self.inputs.pop_front() {
                Some((_, old)) => self.input_bytes -= old.data.len(),
                None => break,
            }
        }
    }

    /// A bin's render, stamped with the bin's first-frame arrival on the node's clock; the
    /// left image received nearest that time becomes the bin's input picture.
    pub fn render(&mut self, bin_id: u64, arrival_ns: i64, png: Vec<u8>) {
        self.render = Some(Picture {
            bin_id,
            png: Arc::new(png),
        });
        let nearest = self
            .inputs
            .iter()
            .min_by_key(|(t, _)| t.abs_diff(arrival_ns))
            .map(|(_, img)| img);
        if let Some(png) = nearest.and_then(image_png) {
            self.input = Some(Picture {
                bin_id,
                png: Arc::new(png),
            });
        }
    }

    /// The bird's-eye view.
    pub fn bev(&mut self, png: Vec<u8>) {
        let bin_id = self.latency.back().map_or(0, |l| l.bin_id);
        self.bev = Some(Picture {
            bin_id,
            png: Arc::new(png),
        });
    }

    /// A message that did not decode.
    pub fn undecodable(&mut self) {
        self.undecodable += 1;
    }

    /// The latest render, input or bird's-eye picture by name.
    pub fn picture(&self, name: &str) -> Option<Picture> {
        match name {
            "render" => self.render.clone(),
            "input" => self.input.clone(),
            "bev" => self.bev.clone(),
            _ => None,
        }
    }

    /// The map as a 3DGS PLY relative to the origin, with its version (built once per
    /// version). `None` before the map has Gaussians.
    pub fn map_ply(&mut self) -> Option<(u64, Arc<Vec<u8>>)> {
        let origin = self.origin?;
        if self.tiles.is_empty() {
            return None;
        }
        if let Some((v, bytes)) = &self.ply_cache {
            if *v == self.map_version {
                return Some((*v, bytes.clone()));
            }
        }
        let bytes = ply_of(self.tiles.gaussians(), origin)?;
        let entry = (self.map_version, Arc::new(bytes));
        self.ply_cache = Some(entry.clone());
        Some(entry)
    }

    /// The map's tiles (held or let go) within `radius` metres of `point` (page
    /// coordinates: relative to the origin), nearest first, until `budget` Gaussians are
    /// listed ([`super::tiles::ViewTiles::near`]), as the page's JSON: `{"version",
    /// "tile_m", "tiles": [{"x", "y", "version", "gaussians", "take", "held"}]}`; `take`
    /// is how many of the tile's Gaussians to ask `/map/tile.ply` for.
    pub fn tiles_near(&self, point: DVec3, radius: f64, budget: usize) -> Value {
        let world = self.origin.unwrap_or(DVec3::ZERO) + point;
        let tiles: Vec<Value> = self
            .tiles
            .near(world, radius, budget)
            .into_iter()
            .map(|t| {
                let ((x, y), info) = (t.key, t.info);
                json!({
                    "x": x, "y": y, "version": info.version,
                    "gaussians": info.gaussians, "take": t.take, "held": info.held,
                })
            })
            .collect();
        json!({
            "version": self.map_version,
            "tile_m": self.tiles.rules().side_m,
            "tiles": tiles,
        })
    }

    /// One tile as a 3DGS PLY relative to the origin, with its version: all its Gaussians,
    /// or its `take` most opaque (`tiles::most_opaque`).
    pub fn tile_ply(&mut self, tile: TileKey, take: Option<usize>) -> TilePly {
        let Some(origin) = self.origin else {
            return TilePly::Unknown;
        };
        match self.tiles.tile(tile) {
            Some((version, gaussians)) => {
                let bytes = match take {
                    Some(take) if take < gaussians.len() => {
                        let kept = most_opaque(&gaussians, take);
                        ply_of(kept.into_iter().map(|i| &gaussians[i]), origin)
                    }
                    _ => ply_of(gaussians.iter(), origin),
                };
                match bytes {
                    Some(bytes) => TilePly::Ready(version, bytes),
                    None => TilePly::Unknown,
                }
            }
            None if self.tiles.is_let_go(tile) => TilePly::Fetching,
            None => TilePly::Unknown,
        }
    }

    /// The let-go tiles the page asked for, with their world ground boxes (lower and upper
    /// corners), for the watcher to fetch from the node.
    pub fn wanted_tiles(&self) -> Vec<(TileKey, (DVec2, DVec2))> {
        let tiles = &self.tiles;
        tiles
            .wanted()
            .into_iter()
            .map(|k| (k, tiles.bounds(k)))
            .collect()
    }

    /// What the node answered for the wanted `tiles` (see [`ViewTiles::fetched`]).
    pub fn tiles_fetched(&mut self, tiles: &[TileKey], gaussians: &[(GaussianId, WorldGaussian)]) {
        self.tiles.fetched(tiles, gaussians);
    }

    /// A view whose tiles follow `rules` (the default's otherwise).
    pub fn with_tiles(rules: TileRules) -> Self {
        Self {
            tiles: ViewTiles::new(rules),
            ..Self::default()
        }
    }

    /// Takes the node's tile side (from a whole-map snapshot's reply) when the view knows
    /// no tile yet, so that the tiles the node names map one to one onto the view's.
    pub fn adopt_tile_side(&mut self, side_m: f64) {
        let rules = self.tiles.rules();
        let valid = side_m.is_finite() && side_m > 0.0;
        if valid && self.tiles.tile_counts() == (0, 0) && side_m != rules.side_m {
            self.tiles = ViewTiles::new(TileRules { side_m, ..rules });
        }
    }

    /// What a whole-map snapshot's reply says the node keeps on disk: its tile side and
    /// the tiles (key, Gaussians), known from then on as let-go tiles to fetch when the
    /// page comes near. A view on another grid ignores them (it still fetches what it let
    /// go itself).
    pub fn paged_on_node(&mut self, side_m: f64, tiles: &[(TileKey, usize)]) {
        if self.tiles.rules().side_m != side_m || tiles.is_empty() {
            return;
        }
        self.map_version += 1;
        self.tiles.paged_on_node(tiles, self.map_version);
        // A map wholly on disk gives the view no Gaussian to take its origin from.
        if self.origin.is_none() {
            let (lo, hi) = self.tiles.bounds(tiles[0].0);
            self.origin = Some(((lo + hi) / 2.0).extend(0.0));
        }
    }

    /// A view of a saved map that will not change: every Gaussian held (whatever the
    /// rules' keep range), the origin at the first one. `None` for an empty map.
    pub fn saved(gaussians: Vec<WorldGaussian>, side_m: f64) -> Option<Self> {
        let mut st = Self::with_tiles(TileRules {
            side_m,
            keep_m: f64::MAX,
            ..TileRules::default()
        });
        let snapshot = crate::fusion::Snapshot {
            last_bin_id: None,
            gaussians: (0u64..).map(GaussianId).zip(gaussians).collect(),
        };
        st.map_update(0, Update::Snapshot(snapshot));
        st.origin?;
        Some(st)
    }

    /// The world point the page's coordinates are relative to (`None` before the map or a
    /// bin arrived).
    pub fn origin(&self) -> Option<DVec3> {
        self.origin
    }

    /// Everything but the pictures and the map, as the page's JSON.
    pub fn to_json(&self) -> Value {
        let origin = self.origin.unwrap_or(DVec3::ZERO);
        let (held, let_go) = self.tiles.tile_counts();
        let bins: Vec<Value> = self
            .bins
            .iter()
            .map(|(stamp, pose)| {
                let id = self
                    .latency
                    .iter()
                    .find(|l| l.first_frame_arrival_ns == *stamp)
                    .map(|l| l.bin_id);
                let r = pose.matrix3;
                let p = pose.translation - origin;
                json!({
                    "bin_id": id,
                    "rotation_rows": [r.row(0).to_array(), r.row(1).to_array(), r.row(2).to_array()],
                    "position": p.to_array(),
                })
            })
            .collect();
        let latency: Vec<Value> = self
            .latency
            .iter()
            .map(|l| {
                let stages: serde_json::Map<String, Value> = bin_stages_ms(l)
                    .iter()
                    .map(|(name, ms)| (name.to_string(), json!(ms)))
                    .collect();
                json!({
                    "bin_id": l.bin_id,
                    "stages_ms": stages,
                    "queue_depth": l.queue_depth,
                    "drops": l.drops,
                    "bad_messages": l.bad_messages,
                    "check_verdict": l.check_verdict,
                    "check_score": l.check_score,
                    "operating_point": l.operating_point,
                })
            })
            .collect();
        let picture = |p: &Option<Picture>| p.as_ref().map(|p| p.bin_id);
        let counters: serde_json::Map<String, Value> = self
            .counters
            .iter()
            .map(|(k, v)| (k.clone(), json!(v)))
            .collect();
        json!({
            "map": {
                "version": self.map_version,
                "sequence": self.sequence,
                "gaussians": self.tiles.len(),
                "tile_m": self.tiles.rules().side_m,
                "tiles_held": held,
                "tiles_let_go": let_go,
                "skipped_removals": self.tiles.skipped_removals(),
                "origin": self.origin.map(|o| o.to_array()),
            },
            "bins": bins,
            "bins_seen": self.bins_seen,
            "latency": latency,
            "counters": counters,
            "intrinsics": self.intrinsics.map(|k| json!({
                "fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy,
                "width": k.width, "height": k.height,
            })),
            "pictures": {
                "render": picture(&self.render),
                "input": picture(&self.input),
                "bev": picture(&self.bev),
            },
            "undecodable": self.undecodable,
        })
    }
}

/// What [`ViewState::tile_ply`] has for a tile.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TilePly {
    /// The tile's PLY, with its version.
    Ready(u64, Vec<u8>),
    /// A let-go tile being fetched from the node: ask again.
    Fetching,
    /// No such tile (or no map yet).
    Unknown,
}

/// World Gaussians as a 3DGS PLY relative to `origin` (`None` if they do not convert).
fn ply_of<'a>(
    gaussians: impl IntoIterator<Item = &'a WorldGaussian>,
    origin: DVec3,
) -> Option<Vec<u8>> {
    let set = local_set(gaussians, DAffine3::from_translation(origin)).ok()?;
    let mut bytes = Vec::new();
    renderer::ply::write_ply(&set, &mut bytes).ok()?;
    Some(bytes)
}

/// An `rgb8`/`bgr8`/`mono8` image message as PNG (`None` if it does not decode).
fn image_png(msg: &Image) -> Option<Vec<u8>> {
    let rgb = crate::msg::image::rgb_from_image(msg).ok()?;
    rgb_png(rgb.width, rgb.height, rgb.to_rgb8())
}

/// Packed RGB bytes as PNG.
pub fn rgb_png(width: u32, height: u32, rgb: Vec<u8>) -> Option<Vec<u8>> {
    let img = image::RgbImage::from_raw(width, height, rgb)?;
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).ok()?;
    Some(out.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::{GaussianId, Increment, Snapshot, WorldGaussian};

    fn gaussian(x: f64) -> WorldGaussian {
        super::super::test_gaussian::at(DVec3::new(x, 2.0, 3.0))
    }

    fn increment(bin_id: u64, ids: &[u64]) -> Update {
        Update::Increment(Increment {
            bin_id,
            added: ids
                .iter()
                .map(|&i| (GaussianId(i), gaussian(i as f64)))
                .collect(),
            ..Increment::default()
        })
    }

    #[test]
    fn increments_apply_in_sequence_and_a_gap_asks_for_a_snapshot() {
        let mut st = ViewState::default();
        assert!(st.map_ply().is_none(), "no map yet");
        assert_eq!(st.map_update(1, increment(0, &[0, 1])), MapSync::InSync);
        assert_eq!(st.map_update(2, increment(1, &[2])), MapSync::InSync);
        assert_eq!(
            st.map_update(2, increment(1, &[2])),
            MapSync::InSync,
            "a repeat"
        );
        assert_eq!(st.map_update(4, increment(3, &[4])), MapSync::NeedsSnapshot);
        let snapshot = Snapshot {
            last_bin_id: Some(3),
            gaussians: (0..5)
                .map(|i| (GaussianId(i), gaussian(i as f64)))
                .collect(),
        };
        assert_eq!(
            st.map_update(4, Update::Snapshot(snapshot)),
            MapSync::InSync
        );
        assert_eq!(st.map_update(5, increment(4, &[5])), MapSync::InSync);
        let json = st.to_json();
        assert_eq!(json["map"]["gaussians"], 6);
        assert_eq!(json["map"]["sequence"], 5);
        // The PLY is relative to the first Gaussian seen (x = 0), built once per version.
        let (version, ply) = st.map_ply().unwrap();
        let set = renderer::ply::read_ply(ply.as_slice()).unwrap();
        assert_eq!(set.len(), 6);
        assert_eq!(st.map_ply().unwrap().0, version);
        assert!(Arc::ptr_eq(&st.map_ply().unwrap().1, &ply), "cached");
    }

    #[test]
    fn a_late_view_waits_for_a_snapshot_and_input_images_stay_within_their_budget() {
        let mut st = ViewState::default();
        assert_eq!(st.map_update(7, increment(6, &[9])), MapSync::NeedsSnapshot);
        let image = |n: usize| Image {
            data: vec![0; n],
            ..Image::default()
        };
        for i in 0..100 {
            st.input_image(i, image(1 << 20));
        }
        assert!(st.input_bytes <= MAX_INPUT_BYTES);
        assert_eq!(st.inputs.len(), MAX_INPUT_BYTES >> 20);
        assert_eq!(
            st.inputs.front().map(|(t, _)| *t),
            Some(100 - (MAX_INPUT_BYTES >> 20) as i64)
        );
    }
}
