//! `stereosplat view` (the live page for a node running elsewhere on the zenoh network) and
//! the `--view` flags of `run` and `demo`, which serve the same page beside their node.

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result};
use clap::Args;

use super::common::shutdown::shutdown_signal;
use super::common::zenoh_args::ZenohArgs;
use zenoh::Session;

use crate::fusion::AtTornTail;
use crate::store::map_files::{restore, whole_map, CHECKPOINT};
use crate::transport::open;
use crate::transport::Keys;
use crate::view::{default_node_modules, Bound, View, ViewConfig, ViewState};

/// Flags of `view`.
#[derive(Args, Clone, Debug)]
pub struct ViewArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// Address the page is served on (loopback by default; another prints a warning).
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    bind: IpAddr,
    /// Port the page is served on (0: any free one, printed).
    #[arg(long, default_value_t = 8090)]
    port: u16,
    /// The `node_modules` folder `npm ci` filled in `view/` (default: `$STEREOSPLAT_VIEW_MODULES`,
    /// then `view/node_modules` beside the executable, then the checkout's).
    #[arg(long, env = "STEREOSPLAT_VIEW_MODULES")]
    node_modules: Option<PathBuf>,
    /// Show a saved map instead of a running node: a folder `run --out` wrote (its
    /// checkpoint, journal and tiles on disk: the whole map) or a PLY, SPZ or glTF binary
    /// map file.
    #[arg(long)]
    map: Option<PathBuf>,
    /// Side of the tiles the page loads, metres.
    #[arg(long, default_value_t = 64.0)]
    tile_m: f64,
}

/// The `--view` flags of `run` and `demo`.
#[derive(Args, Clone, Debug)]
#[command(next_help_heading = "Live view")]
pub struct ViewFlags {
    /// Serve the live view (splats of the global map, renders, latency charts) while the
    /// node runs; `demo` keeps serving after the drive until Ctrl-C.
    #[arg(long)]
    pub view: bool,
    /// Address of the live view.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    view_bind: IpAddr,
    /// Port of the live view (0: any free one, printed).
    #[arg(long, default_value_t = 8090)]
    view_port: u16,
}

impl ViewFlags {
    /// The view's settings.
    pub fn config(&self) -> ViewConfig {
        ViewConfig {
            bind: SocketAddr::new(self.view_bind, self.view_port),
            node_modules: default_modules(None),
        }
    }
}

fn default_modules(flag: Option<&PathBuf>) -> PathBuf {
    flag.cloned().unwrap_or_else(default_node_modules)
}

/// Serves the live view of the node the zenoh flags reach until Ctrl-C or SIGTERM.
pub fn run(args: &ViewArgs) -> Result<()> {
    let config = ViewConfig {
        bind: SocketAddr::new(args.bind, args.port),
        node_modules: default_modules(args.node_modules.as_ref()),
    };
    let runtime = tokio::runtime::Runtime::new()?;
    if let Some(path) = &args.map {
        let state = saved_view(path, args.tile_m)?;
        return runtime.block_on(async {
            let view = Bound::bind(&config).await?.serve_saved(state);
            announce(&view);
            shutdown_signal().await;
            view.stop().await;
            anyhow::Ok(())
        });
    }
    runtime.block_on(async {
        let bound = Bound::bind(&config).await?;
        let session = open(&args.zenoh.transport()).await?;
        let view = bound.serve(&session, args.zenoh.keys());
        announce(&view);
        shutdown_signal().await;
        view.stop().await;
        anyhow::Ok(())
    })
}

/// The view of the saved map at `path`: a folder `run --out` wrote (the whole map: its
/// checkpoint, journal and paged tiles) or a PLY, SPZ or glTF binary file (in its own
/// frame).
pub fn saved_view(path: &Path, tile_m: f64) -> Result<ViewState> {
    let gaussians = saved_view_gaussians(path)?;
    ViewState::saved(gaussians, tile_m)
        .with_context(|| format!("{} holds no Gaussian", path.display()))
}

/// Every Gaussian of the saved map at `path` (see [`saved_view`]).
pub fn saved_view_gaussians(path: &Path) -> Result<Vec<crate::fusion::WorldGaussian>> {
    Ok(if path.is_dir() {
        let restored = restore(path, AtTornTail::Cut)?
            .with_context(|| format!("{} holds no saved map", path.display()))?;
        whole_map(&restored.map, &path.join(CHECKPOINT))?
    } else {
        let file =
            std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
        let (_, set) = renderer::formats::read_map(std::io::BufReader::new(file))
            .with_context(|| format!("reading {}", path.display()))?;
        world_gaussians(&set)
    })
}

/// Prints where the page is (stderr, so stdout keeps a command's own output).
pub fn announce(view: &View) {
    eprintln!("view ready: {}", view.url());
}

/// Where the view started beside a node is kept once the node is ready.
pub type ViewSlot = Arc<Mutex<Option<View>>>;

/// The view beside a node (`run --view`, `demo --view`): with `--view`, binds its address
/// now (so a port in use or missing libraries fail before the node starts) and returns the
/// hook to call with the node's session when it is ready, which starts the view there and
/// puts it in the slot. Without `--view` the hook does nothing.
pub async fn beside(
    flags: &ViewFlags,
    keys: Keys,
) -> Result<(impl FnOnce(&Session) + Send + 'static, ViewSlot)> {
    let bound = match flags.view {
        true => Some(Bound::bind(&flags.config()).await?),
        false => None,
    };
    let slot = ViewSlot::default();
    let filled = slot.clone();
    let hook = move |session: &Session| {
        if let Some(bound) = bound {
            let view = bound.serve(session, keys);
            announce(&view);
            *filled.lock().unwrap_or_else(|e| e.into_inner()) = Some(view);
        }
    };
    Ok((hook, slot))
}

/// Takes the view out of its slot (to stop it).
pub fn take(slot: &ViewSlot) -> Option<View> {
    slot.lock().unwrap_or_else(|e| e.into_inner()).take()
}

/// A map file's Gaussians as map Gaussians in the file's own frame (bin 0).
fn world_gaussians(set: &renderer::GaussianSet) -> Vec<crate::fusion::WorldGaussian> {
    (0..set.len())
        .map(|i| crate::fusion::WorldGaussian {
            position: set.means[i].as_dvec3(),
            log_scale: set.log_scales[i],
            rotation: set.rotations[i],
            opacity: set.opacities[i],
            color: set.colors[i],
            confidence: set.confidences[i],
            bin_id: 0,
        })
        .collect()
}
