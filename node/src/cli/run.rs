//! `stereosplat run`: the streaming node, stereo frames and poses in over zenoh, Gaussian
//! maps out (every flag: docs/node.md).

use std::path::{Path, PathBuf};

use crate::foxglove::FoxgloveConfig;
use crate::fusion::{FusionConfig, Keep, DEFAULT_MAX_RANGE_M};
use crate::pipeline::binner::BinnerConfig;
use crate::pipeline::self_check::OnCheckFail;
use crate::pipeline::sync::SyncConfig;
use crate::pipeline::worker::RenderWith;
use crate::service::{self, InputLimits, NodeConfig, WorkersConfig};
use crate::store::Compaction;
use crate::store::Paging;
use crate::store::StartMap;
use anyhow::Result;
use clap::Args;
use renderer::formats::MapFormat;

use super::common::method_args::MethodArgs;
use super::common::operating_args::OperatingArgs;
use super::common::pose_args::PoseArgs;
use super::common::shutdown::shutdown_signal;
use super::common::units::seconds_ns;
use super::common::zenoh_args::ZenohArgs;
use super::view::{self, ViewFlags};

/// `--renders` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RenderArg {
    /// No renders.
    Off,
    /// The CPU reference rasterizer.
    Cpu,
    /// wgpu (the CPU when no adapter is found).
    Gpu,
    /// wgpu on a hardware GPU, else the CPU reference.
    Auto,
}

impl From<RenderArg> for RenderWith {
    fn from(r: RenderArg) -> Self {
        match r {
            RenderArg::Off => RenderWith::Off,
            RenderArg::Cpu => RenderWith::Cpu,
            RenderArg::Gpu => RenderWith::Gpu,
            RenderArg::Auto => RenderWith::Auto,
        }
    }
}

/// `--on-check-fail` values: what the node does with a bin whose map fails its self-check.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnCheckFailArg {
    /// Publish the map anyway; its latency message and the counters flag it.
    Flag,
    /// Publish it with opacity and confidence scaled by 0.1.
    LowerOpacity,
    /// Publish SGM's map of the bin instead (checked too; flagged if it also fails).
    Sgm,
}

impl From<OnCheckFailArg> for OnCheckFail {
    fn from(a: OnCheckFailArg) -> Self {
        match a {
            OnCheckFailArg::Flag => OnCheckFail::Flag,
            OnCheckFailArg::LowerOpacity => OnCheckFail::LowerOpacity,
            OnCheckFailArg::Sgm => OnCheckFail::Sgm,
        }
    }
}

/// Flags of `run`.
#[derive(Args, Clone, Debug)]
pub struct RunArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// The reconstructor, its preset, weights and settings.
    #[command(flatten)]
    method: MethodArgs,
    /// A latency budget and the operating points that meet it.
    #[command(flatten)]
    operating: OperatingArgs,
    /// What to do with a bin whose map fails the self-check (its own stereo pair does not
    /// agree with the map's geometry; docs/crashes-and-limits.md, "Self-check").
    #[arg(help_heading = "Reconstructor", long, value_enum, default_value_t = OnCheckFailArg::Sgm)]
    on_check_fail: OnCheckFailArg,
    /// Bin length in metres.
    #[arg(help_heading = "Bins and inputs", long, default_value_t = 8.0)]
    bin_length: f64,
    /// Bins waiting for the worker at most (the oldest waiting is dropped beyond it).
    #[arg(help_heading = "Bins and inputs", long, default_value_t = crate::service::DEFAULT_QUEUE)]
    queue: usize,
    /// Where the fused global map is written when the node stops, and where its checkpoint
    /// (`global_map.ssgmap` and `global_map.journal/`) is kept: a node started on a folder
    /// that holds one resumes it
    /// (map, bin ids, sequence numbers); a checkpoint that does not load stops the node.
    #[arg(help_heading = "Map and checkpoint", long, default_value = "out/node")]
    out: PathBuf,
    /// Format of the global map file written to `--out` when the node stops
    /// (`global_map.<ply|spz|glb>`): 3DGS PLY, Niantic's compressed SPZ, or binary glTF with
    /// KHR_gaussian_splatting (docs/formats.md).
    #[arg(help_heading = "Map and checkpoint", long, default_value_t = MapFormat::Ply)]
    format: MapFormat,
    /// Start a new, empty map even if `--out` holds a checkpoint (it is kept, renamed to
    /// `global_map.ssgmap.replaced-<unix seconds>` and `global_map.journal.replaced-<unix
    /// seconds>`).
    #[arg(help_heading = "Map and checkpoint", long)]
    fresh: bool,
    /// Sync the map's journal (`global_map.journal/`, what each bin changed) after every
    /// this many bins, before they are published (0: nothing is written until the node
    /// stops). With 1, a crash loses no bin that was published.
    #[arg(help_heading = "Map and checkpoint", long, default_value_t = 1)]
    checkpoint_every: u64,
    /// Fold the journal into the checkpoint's base file in the background once it holds
    /// this many MiB and at least as many bytes as the base.
    #[arg(help_heading = "Map and checkpoint", long, default_value_t = 64)]
    compact_after_mib: u64,
    /// Keep in memory only the map's tiles within this many metres of the vehicle; farther
    /// tiles are paged to `--out` and read back when the vehicle returns (0: keep the whole
    /// map in memory, evicting past the budget). docs/long-drives.md
    #[arg(help_heading = "Map and checkpoint", long, default_value_t = 200.0)]
    page_radius_m: f64,
    /// Side of the map's square ground tiles, metres (whole 16 m columns)
    #[arg(help_heading = "Map and checkpoint", long, default_value_t = 64.0)]
    tile_m: f64,
    /// Return the memory the allocator keeps after it is freed to the system every this
    /// many seconds, with its arenas capped at one per core, so resident memory follows the
    /// map in memory on a long drive (0: neither). The binary also runs under allocator
    /// settings of its own unless GLIBC_TUNABLES is set (empty: glibc's defaults).
    /// docs/long-drives.md
    #[arg(help_heading = "Outputs", long, default_value_t = 5.0)]
    release_memory_every_s: f64,
    /// Rasterizer of the per-bin renders (input view and bird's-eye view); `off` for none.
    #[arg(help_heading = "Reconstructor", long, value_enum, default_value_t = RenderArg::Auto)]
    renders: RenderArg,
    /// Publish a global map snapshot every this many bins (0: only when queried).
    #[arg(help_heading = "Map and checkpoint", long, default_value_t = 10)]
    snapshot_every: u64,
    /// Publish the counters on `diagnostics` every this many seconds, besides with every
    /// bin (0: only with the bins).
    #[arg(help_heading = "Outputs", long, default_value_t = 1.0)]
    diagnostics_every: f64,
    /// Seconds between a frame's stamp and the last emitted frame's beyond which the input
    /// starts a new timeline (after 3 frames agree): a replay, a clock reset.
    #[arg(help_heading = "Bins and inputs", long, default_value_t = 2.0)]
    sync_jump: f64,
    /// Milliseconds a right image or a pose may lie from the left image's stamp and still be
    /// paired with it (approximate time; below half the frame period). Frames that never
    /// complete are counted (`sync/unmatched`).
    #[arg(help_heading = "Bins and inputs", long, default_value_t = 10.0)]
    sync_slop_ms: f64,
    /// MiB of decoded images the synchroniser holds per stream at most.
    #[arg(help_heading = "Bins and inputs", long, default_value_t = 64)]
    sync_mib_per_stream: usize,
    /// Gaussians of a bin map farther than this from the bin's camera, metres, are
    /// published with the bin but not fused into the global map (sky and far, weakly
    /// supported depth; `inf` fuses everything); docs/evaluation.md, "The fused map's own quality".
    #[arg(help_heading = "Map and checkpoint", long, default_value_t = DEFAULT_MAX_RANGE_M)]
    map_keep_range: f32,
    /// Leave every bin to worker processes (`stereosplat worker`): the node runs no
    /// reconstructor itself, and bins wait (up to --queue) until a worker joins.
    #[arg(help_heading = "Workers", long)]
    no_local_worker: bool,
    /// Seconds a worker process may hold a bin without sending its map before the bin
    /// goes to another worker (its late answer is then discarded and counted).
    #[arg(help_heading = "Workers", long, default_value_t = 60.0)]
    worker_timeout: f64,
    #[command(flatten)]
    limits: LimitsArgs,
    #[command(flatten)]
    poses: PoseArgs,
    #[command(flatten)]
    view: ViewFlags,
    /// Stream the outputs to Foxglove through a WebSocket server made with Foxglove's SDK
    /// (docs/foxglove.md), on this address (loopback by default; another prints a warning;
    /// port 0: any free one, printed).
    #[arg(help_heading = "Outputs", long, value_name = "ADDR:PORT", num_args = 0..=1,
          default_missing_value = crate::foxglove::DEFAULT_ADDR)]
    foxglove: Option<std::net::SocketAddr>,
}

impl RunArgs {
    /// The node's out folder (`--out`).
    pub fn out_dir(&self) -> &Path {
        &self.out
    }
}

/// The input limits a user may change (`node::service::InputLimits`; the rest keep their
/// defaults). A message or image above them is refused and counted as `refused/<reason>`.
#[derive(Args, Debug, Clone)]
#[command(next_help_heading = "Input limits")]
pub struct LimitsArgs {
    /// MiB an input message may hold at most.
    #[arg(long, default_value_t = 32)]
    max_message_mib: usize,
    /// Pixels an input image may have at most (default 3840 x 2160).
    #[arg(long, default_value_t = 3840 * 2160)]
    max_image_pixels: u64,
    /// Pixels the reconstructor is given at most; larger images are area-averaged down
    /// (default 1408 x 376, KITTI-360's rectified size). More costs worker time and memory.
    #[arg(long, default_value_t = 1408 * 376)]
    working_pixels: u64,
    /// Seconds between two answered snapshot queries at least.
    #[arg(long, default_value_t = 1.0)]
    snapshot_interval: f64,
}

impl LimitsArgs {
    /// The node's limits with these flags applied.
    fn limits(&self) -> Result<InputLimits> {
        anyhow::ensure!(
            self.working_pixels > 0 && self.max_image_pixels > 0,
            "--working-pixels and --max-image-pixels must be positive"
        );
        let interval = seconds_ns(self.snapshot_interval, "--snapshot-interval")?;
        Ok(InputLimits {
            max_message_bytes: self.max_message_mib.saturating_mul(1 << 20),
            max_pixels: self.max_image_pixels,
            max_working_pixels: self.working_pixels,
            snapshot_interval: std::time::Duration::from_nanos(interval as u64),
            ..InputLimits::default()
        })
    }
}

/// Runs the node until Ctrl-C or SIGTERM.
pub fn run(args: &RunArgs) -> Result<()> {
    let config = node_config(args)?;
    if args.operating.calibrate && args.operating.latency_budget.is_none() {
        // A calibration alone: the table is written, and no budget asks for a node.
        return Ok(());
    }
    let runtime = tokio::runtime::Runtime::new()?;
    let namespace = config.keys.namespace.clone();
    let keys = config.keys.clone();
    let summary = runtime.block_on(async {
        let (start_view, view) = view::beside(&args.view, keys).await?;
        let summary = service::run_announced(config, shutdown_signal(), |session| {
            eprintln!("node ready: {namespace}");
            start_view(session);
        })
        .await;
        if let Some(view) = view::take(&view) {
            view.stop().await;
        }
        anyhow::Ok(summary?)
    })?;
    println!(
        "{}",
        serde_json::json!({
            "bins_published": summary.bins_published,
            "global_gaussians": summary.global_gaussians,
            "counters": summary.counters,
            "out": args.out,
        })
    );
    Ok(())
}

/// The node `run`'s flags describe (with `--calibrate`, the operating table is measured
/// and written on the way).
fn node_config(args: &RunArgs) -> Result<NodeConfig> {
    Ok(args.method.node_config(NodeConfig {
        transport: args.zenoh.transport(),
        keys: args.zenoh.keys(),
        sync: SyncConfig {
            jump_ns: seconds_ns(args.sync_jump, "--sync-jump")?,
            slop_ns: slop_ns(args.sync_slop_ms)?,
            max_bytes_per_stream: args.sync_mib_per_stream.saturating_mul(1 << 20),
            ..SyncConfig::default()
        },
        diagnostics_every: std::time::Duration::from_nanos(seconds_ns(
            args.diagnostics_every,
            "--diagnostics-every",
        )? as u64),
        binner: BinnerConfig {
            length_m: args.bin_length,
            ..BinnerConfig::default()
        },
        queue_capacity: args.queue,
        pose_source: args.poses.config()?,
        world_frame: args.poses.world_frame(),
        on_check_fail: args.on_check_fail.into(),
        fusion: FusionConfig {
            keep: Keep {
                max_range_m: args.map_keep_range,
                ..Keep::default()
            },
            tile_m: args.tile_m,
            ..FusionConfig::default()
        },
        out_dir: Some(args.out.clone()),
        map_format: args.format,
        start_map: match args.fresh {
            true => StartMap::Fresh,
            false => StartMap::Resume,
        },
        checkpoint_every: args.checkpoint_every,
        compaction: Compaction {
            min_bytes: args.compact_after_mib.saturating_mul(1 << 20),
        },
        paging: page_radius(args.page_radius_m)?,
        release_memory_every: std::time::Duration::from_nanos(seconds_ns(
            args.release_memory_every_s,
            "--release-memory-every-s",
        )? as u64),
        renders: args.renders.into(),
        snapshot_every: args.snapshot_every,
        limits: args.limits.limits()?,
        foxglove: args.foxglove.map(|bind| FoxgloveConfig {
            bind,
            ..FoxgloveConfig::default()
        }),
        operating: args.operating.operating(&args.out)?,
        workers: WorkersConfig {
            local: !args.no_local_worker,
            timeout: std::time::Duration::from_nanos(seconds_ns(
                args.worker_timeout,
                "--worker-timeout",
            )? as u64),
        },
        ..NodeConfig::default()
    }))
}

/// `--page-radius-m`: `None` at 0 (no paging), else the radius.
fn page_radius(metres: f64) -> Result<Option<Paging>> {
    anyhow::ensure!(
        metres.is_finite() && metres >= 0.0,
        "--page-radius-m must be a distance in metres from 0, not {metres}"
    );
    Ok((metres > 0.0).then_some(Paging { radius_m: metres }))
}

/// `--sync-slop-ms` in nanoseconds.
fn slop_ns(ms: f64) -> Result<i64> {
    anyhow::ensure!(
        ms.is_finite() && (0.0..1000.0).contains(&ms),
        "--sync-slop-ms must be a number of milliseconds in [0, 1000), not {ms}"
    );
    Ok((ms * 1e6) as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(extra: &[&str]) -> Result<InputLimits> {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            limits: LimitsArgs,
        }
        let args = std::iter::once("run").chain(extra.iter().copied());
        <Cli as clap::Parser>::try_parse_from(args)?.limits.limits()
    }

    #[test]
    fn limit_flags_set_the_node_limits_and_keep_the_other_defaults() {
        assert_eq!(limits(&[]).unwrap(), InputLimits::default());
        let l = limits(&[
            "--max-message-mib",
            "8",
            "--max-image-pixels",
            "1000000",
            "--working-pixels",
            "20000",
            "--snapshot-interval",
            "0.25",
        ])
        .unwrap();
        assert_eq!(l.max_message_bytes, 8 << 20);
        assert_eq!((l.max_pixels, l.max_working_pixels), (1_000_000, 20_000));
        assert_eq!(l.snapshot_interval, std::time::Duration::from_millis(250));
        assert_eq!(
            l.max_translation_m,
            InputLimits::default().max_translation_m
        );
    }

    #[test]
    fn the_foxglove_flag_is_off_loopback_by_default_or_the_address_given() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            run: RunArgs,
        }
        let foxglove = |extra: &[&str]| {
            let args = std::iter::once("run").chain(extra.iter().copied());
            <Cli as clap::Parser>::try_parse_from(args).map(|c| c.run.foxglove)
        };
        assert_eq!(foxglove(&[]).unwrap(), None);
        let default = crate::foxglove::DEFAULT_ADDR.parse().ok();
        assert_eq!(foxglove(&["--foxglove"]).unwrap(), default);
        assert_eq!(
            foxglove(&["--foxglove", "[::1]:0"]).unwrap(),
            "[::1]:0".parse().ok()
        );
        assert!(foxglove(&["--foxglove", "localhost"]).is_err());
    }

    #[test]
    fn runs_defaults_are_the_nodes() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            run: RunArgs,
        }
        let args = <Cli as clap::Parser>::try_parse_from(["run"]).unwrap().run;
        let (flags, node) = (node_config(&args).unwrap(), NodeConfig::default());
        assert_eq!(flags.queue_capacity, node.queue_capacity);
        assert_eq!(flags.queue_capacity, crate::service::DEFAULT_QUEUE);
        assert_eq!(flags.binner, node.binner);
        assert_eq!(flags.sync, node.sync);
        assert_eq!(flags.world_frame, node.world_frame);
        assert_eq!(flags.limits, node.limits);
    }

    #[test]
    fn impossible_limits_are_refused() {
        assert!(limits(&["--working-pixels", "0"]).is_err());
        assert!(limits(&["--snapshot-interval", "-1"]).is_err());
        assert!(limits(&["--snapshot-interval", "NaN"]).is_err());
    }
}
