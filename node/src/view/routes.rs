//! What the live view's server answers, by path (GET, and HEAD with the same headers and no
//! body; any other path is 404, any other method 405):
//!
//! | path | what |
//! | --- | --- |
//! | `/` | the page (`view/index.html`, built into the binary) |
//! | `/app.js` | the page's script (`view/app.js`, built in) |
//! | `/lib/three/three.module.js`, `/lib/three/three.core.js` | three.js, from `view/node_modules` |
//! | `/lib/splats/gaussian-splats-3d.module.js` | the splat viewer, from `view/node_modules` |
//! | `/api/state` | JSON: map version and size, bin cameras, latency rows, counters |
//! | `/map.ply` | the map the view holds as one 3DGS PLY relative to the state's `map.origin`; header `X-Map-Version` |
//! | `/api/tiles?x=X&y=Y[&radius=R][&budget=N]` | JSON: the map's tiles within `R` metres (default [`DEFAULT_RADIUS_M`]) of the page point `(X, Y)` (relative to `map.origin`), nearest first, until `N` Gaussians (default [`DEFAULT_BUDGET`]; the last tile's `take` may be part of it) |
//! | `/map/tile.ply?x=TX&y=TY[&take=N]` | one tile (its `N` most opaque Gaussians with `take`, as `/api/tiles` lists) as 3DGS PLY relative to `map.origin`; header `X-Tile-Version`; 503 with `Retry-After` while a tile the view let go is fetched from the node |
//! | `/render.png`, `/input.png`, `/bev.png` | the latest bin's render and input, the bird's-eye view; header `X-Bin-Id` |
//!
//! Paths are matched whole against this table and never joined onto a folder: a library
//! file is served only under its own URL, so no path (`..` or not) reaches another file.
//! Every answer carries `Cache-Control: no-store` (the page polls) and
//! `X-Content-Type-Options: nosniff`. A request whose `Host` is neither an address nor
//! `localhost` is refused with 421 before any of this ([`super::host`]).
//!
//! The libraries come from the folder `npm ci` filled (setup does it); nothing is fetched
//! from elsewhere, and the page names no other host.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use axum::body::{Body, Bytes};
use axum::extract::State;
use axum::http::{header, HeaderName, HeaderValue, Method, StatusCode, Uri};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;

use super::state::{TilePly, ViewState};
use crate::fusion::TileKey;

/// The page.
const INDEX_HTML: &str = include_str!("../../../view/index.html");
/// The page's script.
const APP_JS: &str = include_str!("../../../view/app.js");

/// Library files the page may load: URL path and file under the `node_modules` folder.
const LIBRARIES: [(&str, &str); 3] = [
    ("/lib/three/three.module.js", "three/build/three.module.js"),
    ("/lib/three/three.core.js", "three/build/three.core.js"),
    (
        "/lib/splats/gaussian-splats-3d.module.js",
        "@mkkellogg/gaussian-splats-3d/build/gaussian-splats-3d.module.js",
    ),
];

const JAVASCRIPT: &str = "text/javascript; charset=utf-8";
const TEXT: &str = "text/plain; charset=utf-8";

/// What the handlers share: the view's state and the libraries' folder.
#[derive(Clone)]
struct Shared {
    state: Arc<Mutex<ViewState>>,
    node_modules: Arc<Path>,
}

impl Shared {
    /// The state; a handler that panicked while holding it left nothing half-written that
    /// matters to a reader, so a poisoned lock is taken as it is.
    fn state(&self) -> MutexGuard<'_, ViewState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The view's router: answers from `state` and the libraries under `node_modules`.
pub fn router(state: Arc<Mutex<ViewState>>, node_modules: PathBuf) -> Router {
    let mut router = Router::new()
        .route("/", get(index))
        .route("/index.html", get(index))
        .route("/app.js", get(app_js))
        // Browsers ask for it unprompted; an empty answer keeps their consoles clean.
        .route("/favicon.ico", get(favicon))
        .route("/api/state", get(api_state))
        .route("/map.ply", get(map_ply))
        .route("/api/tiles", get(api_tiles))
        .route("/map/tile.ply", get(tile_ply))
        .route("/render.png", get(picture("render")))
        .route("/input.png", get(picture("input")))
        .route("/bev.png", get(picture("bev")));
    for (url, file) in LIBRARIES {
        router = router.route(
            url,
            get(move |State(s): State<Shared>| async move { library(&s.node_modules, file) }),
        );
    }
    router
        .fallback(unknown)
        .layer(axum::middleware::map_response(no_store))
        .layer(axum::middleware::from_fn(super::host::check_host))
        .with_state(Shared {
            state,
            node_modules: node_modules.into(),
        })
}

async fn index() -> Response {
    ok("text/html; charset=utf-8", INDEX_HTML)
}

async fn app_js() -> Response {
    ok(JAVASCRIPT, APP_JS)
}

async fn favicon() -> Response {
    ok("image/x-icon", Bytes::new())
}

async fn api_state(State(s): State<Shared>) -> Response {
    let json = s.state().to_json().to_string();
    ok("application/json", json)
}

async fn map_ply(State(s): State<Shared>) -> Response {
    // The lock is released before the body is written: the bytes are shared, not copied.
    let ply = s.state().map_ply();
    match ply {
        Some((version, bytes)) => with_header(
            ok("application/octet-stream", shared(bytes)),
            "x-map-version",
            version,
        ),
        None => error(StatusCode::NOT_FOUND, "no map yet"),
    }
}

/// Tiles listed by `/api/tiles` around the page's point, metres, unless it asks otherwise.
pub const DEFAULT_RADIUS_M: f64 = 160.0;
/// Gaussians listed by `/api/tiles` at most, unless the page asks otherwise.
pub const DEFAULT_BUDGET: usize = 1_000_000;
/// The largest radius a page may ask for, metres.
pub const MAX_RADIUS_M: f64 = 100_000.0;
/// The largest Gaussian budget a page may ask for.
pub const MAX_BUDGET: usize = 50_000_000;

/// What `/api/tiles` asks for, checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TilesQuery {
    /// The page's point, relative to the map's origin (ground x-y, z 0).
    pub point: glam::DVec3,
    /// Metres around it.
    pub radius: f64,
    /// Gaussians listed at most.
    pub budget: usize,
}

/// The parameters of an `/api/tiles` request (see the table above), or the words of the
/// 400 answer to it.
pub fn tiles_query(uri: &Uri) -> Result<TilesQuery, String> {
    let params = params(uri, &["x", "y", "radius", "budget"])?;
    let (Some(x), Some(y)) = (params[0], params[1]) else {
        return Err("/api/tiles needs x and y".into());
    };
    let radius = params[2].unwrap_or(DEFAULT_RADIUS_M);
    let budget = params[3].unwrap_or(DEFAULT_BUDGET as f64);
    if !(0.0..=MAX_RADIUS_M).contains(&radius) || !(1.0..=MAX_BUDGET as f64).contains(&budget) {
        return Err(format!(
            "radius must be in 0..={MAX_RADIUS_M} m and budget in 1..={MAX_BUDGET}"
        ));
    }
    Ok(TilesQuery {
        point: glam::DVec3::new(x, y, 0.0),
        radius,
        budget: budget as usize,
    })
}

/// What `/map/tile.ply` asks for, checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileQuery {
    /// The tile.
    pub tile: TileKey,
    /// Its most opaque Gaussians to send, or all of them.
    pub take: Option<usize>,
}

/// The parameters of a `/map/tile.ply` request (see the table above), or the words of the
/// 400 answer to it.
pub fn tile_query(uri: &Uri) -> Result<TileQuery, String> {
    let params = params(uri, &["x", "y", "v", "take"])?;
    let whole = |v: Option<f64>| v.filter(|v| v.fract() == 0.0 && v.abs() < 1e15);
    let (Some(x), Some(y)) = (whole(params[0]), whole(params[1])) else {
        return Err("/map/tile.ply needs whole numbers x and y".into());
    };
    let take = match params[3] {
        None => None,
        Some(t) if t.fract() == 0.0 && (1.0..=MAX_BUDGET as f64).contains(&t) => Some(t as usize),
        Some(_) => return Err(format!("take must be a whole number in 1..={MAX_BUDGET}")),
    };
    Ok(TileQuery {
        tile: (x as i64, y as i64),
        take,
    })
}

async fn api_tiles(State(s): State<Shared>, uri: Uri) -> Response {
    let q = match tiles_query(&uri) {
        Ok(q) => q,
        Err(e) => return error(StatusCode::BAD_REQUEST, &e),
    };
    let json = s
        .state()
        .tiles_near(q.point, q.radius, q.budget)
        .to_string();
    ok("application/json", json)
}

async fn tile_ply(State(s): State<Shared>, uri: Uri) -> Response {
    let q = match tile_query(&uri) {
        Ok(q) => q,
        Err(e) => return error(StatusCode::BAD_REQUEST, &e),
    };
    let answer = s.state().tile_ply(q.tile, q.take);
    match answer {
        TilePly::Ready(version, bytes) => with_header(
            ok("application/octet-stream", bytes),
            "x-tile-version",
            version,
        ),
        TilePly::Fetching => with_header(
            error(
                StatusCode::SERVICE_UNAVAILABLE,
                "fetching the tile from the node",
            ),
            "retry-after",
            1,
        ),
        TilePly::Unknown => error(StatusCode::NOT_FOUND, "no such tile"),
    }
}

/// The numeric query parameters `names` of `uri`, in that order (absent: `None`). Another
/// parameter, a repeated one or a value that is not a finite number is an error naming it.
fn params(uri: &Uri, names: &[&str]) -> Result<Vec<Option<f64>>, String> {
    let mut out = vec![None; names.len()];
    for pair in uri
        .query()
        .unwrap_or("")
        .split('&')
        .filter(|p| !p.is_empty())
    {
        let (name, value) = pair.split_once('=').unwrap_or((pair, ""));
        let Some(i) = names.iter().position(|n| *n == name) else {
            return Err(format!(
                "unknown parameter `{name}` (this path takes {})",
                names.join(", ")
            ));
        };
        let v: f64 = value
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| format!("parameter `{name}={value}` is not a finite number"))?;
        if out[i].replace(v).is_some() {
            return Err(format!("parameter `{name}` given twice"));
        }
    }
    Ok(out)
}

/// The handler of the latest picture called `name` (see [`ViewState::picture`]).
fn picture(
    name: &'static str,
) -> impl Fn(State<Shared>) -> std::future::Ready<Response> + Clone + Send + Sync + 'static {
    move |State(s): State<Shared>| {
        let picture = s.state().picture(name);
        std::future::ready(match picture {
            Some(p) => with_header(ok("image/png", shared(p.png)), "x-bin-id", p.bin_id),
            None => error(StatusCode::NOT_FOUND, "nothing yet"),
        })
    }
}

/// Any other path: 404 to GET and HEAD, 405 to other methods.
async fn unknown(method: Method) -> Response {
    if method == Method::GET || method == Method::HEAD {
        error(StatusCode::NOT_FOUND, "not found")
    } else {
        error(StatusCode::METHOD_NOT_ALLOWED, "only GET and HEAD")
    }
}

/// Adds the headers every answer carries.
async fn no_store(mut r: Response) -> Response {
    let h = r.headers_mut();
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    r
}

/// A library file read from `node_modules` (503 when the libraries are not installed).
fn library(node_modules: &Path, file: &str) -> Response {
    let path = node_modules.join(file);
    match std::fs::read(&path) {
        Ok(bytes) => ok(JAVASCRIPT, bytes),
        Err(e) => error(
            StatusCode::SERVICE_UNAVAILABLE,
            &format!(
                "{}: {e}; install the view's libraries with `bash .ci/setup` (npm ci in view/)",
                path.display()
            ),
        ),
    }
}

/// 200 with `body` as `content_type`.
fn ok(content_type: &'static str, body: impl Into<Body>) -> Response {
    (
        [(header::CONTENT_TYPE, HeaderValue::from_static(content_type))],
        body.into(),
    )
        .into_response()
}

/// An error status with a one-line text body.
fn error(status: StatusCode, text: &str) -> Response {
    (
        status,
        [(header::CONTENT_TYPE, HeaderValue::from_static(TEXT))],
        format!("{text}\n"),
    )
        .into_response()
}

/// `r` with the header `name: value`.
fn with_header(mut r: Response, name: &'static str, value: u64) -> Response {
    r.headers_mut()
        .insert(HeaderName::from_static(name), HeaderValue::from(value));
    r
}

/// Bytes held by the state, as a body without copying them.
fn shared(bytes: Arc<Vec<u8>>) -> Bytes {
    struct Held(Arc<Vec<u8>>);
    impl AsRef<[u8]> for Held {
        fn as_ref(&self) -> &[u8] {
            &self.0
        }
    }
    Bytes::from_owner(Held(bytes))
}

/// Whether every library file is present under `node_modules` (the first missing one
/// otherwise).
pub fn missing_library(node_modules: &Path) -> Option<PathBuf> {
    LIBRARIES
        .iter()
        .map(|(_, file)| node_modules.join(file))
        .find(|p| !p.is_file())
}
