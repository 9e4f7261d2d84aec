//! The live view: a page served over HTTP on loopback that shows a running node at work —
//! the fused global map as Gaussian splats to fly through (the npm package
//! `@mkkellogg/gaussian-splats-3d` on three.js, served from `view/node_modules`), the
//! latest bin's render beside its input image, the bird's-eye view, and per-stage latency
//! charts with the counters. The page polls `/api/state`; the server is fed by a zenoh
//! session that listens to the node's topics like `monitor` does (`watch`), so it works
//! beside any node: `stereosplat view`, or `--view` on `run` and `demo`. `routes` says
//! what each path answers; `server` serves it with axum on hyper, bounded so that no
//! client can hold the node.

mod host;
mod routes;
mod server;
#[cfg(test)]
mod server_tests;
mod state;
#[cfg(test)]
mod test_gaussian;
mod tiles;
mod watch;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use tokio::net::TcpListener;
use tokio::task::JoinHandle;

use crate::transport::Keys;

pub use routes::{
    tile_query, tiles_query, TileQuery, TilesQuery, DEFAULT_BUDGET, DEFAULT_RADIUS_M, MAX_BUDGET,
    MAX_RADIUS_M,
};
pub use state::{MapSync, TilePly, ViewState, MAX_LATENCY_ROWS};
pub use tiles::{ground_tile, TileInfo, TileRules, TilesError, ViewTiles};
pub use watch::{fetch_batch, paged_tiles, take_sample};

/// Where the view listens and where its browser libraries are.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ViewConfig {
    /// HTTP address (loopback by default; another address prints a warning).
    pub bind: SocketAddr,
    /// The `node_modules` folder `npm ci` filled in `view/`.
    pub node_modules: PathBuf,
}

impl Default for ViewConfig {
    /// `127.0.0.1:8090` and the checkout's `view/node_modules`.
    fn default() -> Self {
        Self {
            bind: SocketAddr::from(([127, 0, 0, 1], 8090)),
            node_modules: default_node_modules(),
        }
    }
}

/// The environment variable naming the folder of the page's browser libraries (a
/// `node_modules` that `npm ci` filled in `view/`).
pub const VIEW_MODULES_ENV: &str = "STEREOSPLAT_VIEW_MODULES";

/// The page's browser libraries, looked for in order: the folder `$STEREOSPLAT_VIEW_MODULES`
/// names, `view/node_modules` beside the executable (an installed binary with its page's
/// libraries copied there), then `view/node_modules` of the checkout the binary was built
/// from. The first that exists; the checkout's when none does (the view then says they are
/// missing).
pub fn default_node_modules() -> PathBuf {
    let exe = std::env::current_exe().ok();
    node_modules_among(std::env::var_os(VIEW_MODULES_ENV), exe.as_deref())
}

/// [`default_node_modules`] for the variable's value `from_env` and the executable `exe`.
fn node_modules_among(from_env: Option<std::ffi::OsString>, exe: Option<&Path>) -> PathBuf {
    let from_env = from_env.filter(|d| !d.is_empty()).map(PathBuf::from);
    let beside_exe = exe.and_then(|e| e.parent().map(|d| d.join("view").join("node_modules")));
    let checkout = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../view/node_modules"));
    from_env
        .into_iter()
        .chain(beside_exe)
        .find(|d| d.is_dir())
        .unwrap_or(checkout)
}

/// Why the view did not start.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The browser libraries are not installed.
    #[error("the live view's libraries are missing ({0}): run `bash .ci/setup` (npm ci in view/)")]
    MissingLibrary(PathBuf),
    /// The HTTP address could not be bound.
    #[error("binding the view to {addr}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
}

/// The view's HTTP address, bound, with its libraries checked: what can fail is done before
/// the node starts. [`Bound::serve`] then starts it on a session.
pub struct Bound {
    listener: TcpListener,
    node_modules: PathBuf,
}

impl Bound {
    /// Checks the libraries and binds `config.bind`. Must be called inside a tokio runtime.
    pub async fn bind(config: &ViewConfig) -> Result<Self, ViewError> {
        if let Some(missing) = routes::missing_library(&config.node_modules) {
            return Err(ViewError::MissingLibrary(missing));
        }
        if !config.bind.ip().is_loopback() {
            eprintln!(
                "warning: the live view listens on {}, which other machines may reach",
                config.bind
            );
        }
        let listener = TcpListener::bind(config.bind)
            .await
            .map_err(|source| ViewError::Bind {
                addr: config.bind,
                source,
            })?;
        Ok(Self {
            listener,
            node_modules: config.node_modules.clone(),
        })
    }

    /// The bound address.
    pub fn addr(&self) -> Result<SocketAddr, ViewError> {
        self.listener
            .local_addr()
            .map_err(|source| ViewError::Bind {
                addr: SocketAddr::from(([127, 0, 0, 1], 0)),
                source,
            })
    }

    /// Serves the page and watches the node's topics under `keys` on `session` (a clone is
    /// kept): the node's own session (`run --view`, `demo --view`: it hears the node's
    /// inputs too) or one connected to the node (`view`). Spawns tokio tasks; a failed
    /// subscription is printed on stderr and leaves the page without updates.
    pub fn serve(self, session: &zenoh::Session, keys: Keys) -> View {
        let addr = self
            .listener
            .local_addr()
            .unwrap_or_else(|_| SocketAddr::from(([127, 0, 0, 1], 0)));
        let state = Arc::new(Mutex::new(ViewState::default()));
        let (stop, stopped) = tokio::sync::watch::channel(false);
        let until_stop = move || {
            let mut rx = stopped.clone();
            async move {
                let _ = rx.wait_for(|s| *s).await;
            }
        };
        let router = routes::router(state.clone(), self.node_modules);
        let server = tokio::spawn(server::serve(
            self.listener,
            router,
            server::Limits::default(),
            until_stop(),
        ));
        let session = session.clone();
        let watcher = tokio::spawn({
            let stop = until_stop();
            async move {
                if let Err(e) = watch::watch(&session, &keys, state, stop).await {
                    eprintln!("view: {e}");
                }
            }
        });
        View {
            addr,
            stop,
            tasks: vec![server, watcher],
        }
    }
}

impl Bound {
    /// Serves the page on a map that does not change (`view --map`: a saved map, with no
    /// node): `state` holds it, and nothing watches a node.
    pub fn serve_saved(self, state: ViewState) -> View {
        let addr = self
            .listener
            .local_addr()
            .unwrap_or_else(|_| SocketAddr::from(([127, 0, 0, 1], 0)));
        let (stop, mut stopped) = tokio::sync::watch::channel(false);
        let router = routes::router(Arc::new(Mutex::new(state)), self.node_modules);
        let server = tokio::spawn(server::serve(
            self.listener,
            router,
            server::Limits::default(),
            async move {
                let _ = stopped.wait_for(|s| *s).await;
            },
        ));
        View {
            addr,
            stop,
            tasks: vec![server],
        }
    }
}

/// A running view: its address, and its tasks until [`View::stop`].
pub struct View {
    addr: SocketAddr,
    stop: tokio::sync::watch::Sender<bool>,
    tasks: Vec<JoinHandle<()>>,
}

impl View {
    /// The address the page is served on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's URL.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Stops serving and watching, and waits for both.
    pub async fn stop(self) {
        let _ = self.stop.send(true);
        for t in self.tasks {
            let _ = t.await;
        }
    }
}

#[cfg(test)]
mod modules_tests {
    use super::*;

    #[test]
    fn the_libraries_are_looked_for_in_the_variable_then_beside_the_binary_then_the_checkout() {
        let root = std::env::temp_dir().join(format!("ss-view-modules-{}", std::process::id()));
        let named = root.join("named");
        let beside = root.join("bin").join("view").join("node_modules");
        std::fs::create_dir_all(&named).unwrap();
        std::fs::create_dir_all(&beside).unwrap();
        let exe = root.join("bin").join("stereosplat");
        let checkout = node_modules_among(None, None);
        assert!(
            checkout.ends_with("view/node_modules"),
            "{}",
            checkout.display()
        );
        assert_eq!(
            node_modules_among(Some(named.clone().into()), Some(&exe)),
            named
        );
        assert_eq!(node_modules_among(None, Some(&exe)), beside);
        // A variable naming no folder, or empty, is passed over.
        let missing = root.join("missing").into_os_string();
        assert_eq!(node_modules_among(Some(missing), Some(&exe)), beside);
        assert_eq!(node_modules_among(Some("".into()), None), checkout);
        let _ = std::fs::remove_dir_all(&root);
    }
}
