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
//! | `/map.ply` | the fused map as 3DGS PLY relative to the state's `map.origin`; header `X-Map-Version` |
//! | `/render.png`, `/input.png`, `/bev.png` | the latest bin's render and input, the bird's-eye view; header `X-Bin-Id` |
//!
//! Paths are matched whole against this table and never joined onto a folder: a library
//! file is served only under its own URL, so no path (`..` or not) reaches another file.
//! Every answer carries `Cache-Control: no-store` (the page polls) and
//! `X-Content-Type-Options: nosniff`.
//!
//! The libraries come from the folder `npm ci` filled (setup does it); nothing is fetched
//! from elsewhere, and the page names no other host.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use axum::body::{Body, Bytes};
use axum::extract::State;
use axum::http::{header, HeaderName, HeaderValue, Method, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;

use super::state::ViewState;

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
