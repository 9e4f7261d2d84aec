//! What the live view's server answers, by path:
//!
//! | path | what |
//! | --- | --- |
//! | `/` | the page (`view/index.html`, built into the binary) |
//! | `/app.js` | the page's script (`view/app.js`, built in) |
//! | `/lib/three/three.module.js`, `/lib/three/three.core.js` | three.js, from `view/node_modules` |
//! | `/lib/splats/gaussian-splats-3d.module.js` | the splat viewer, from `view/node_modules` |
//! | `/api/state` | JSON: map version and size, bin cameras, latency rows, counters |
//! | `/map.ply` | the fused map as 3DGS PLY relative to the state's `map.origin`; header `X-Map-Version` |
//! | `/render.png`, `/input.png`, `/bev.png` | the latest bin's render and input, the bird's-eye view |
//!
//! The libraries come from the folder `npm ci` filled (setup does it); nothing is fetched
//! from elsewhere, and the page names no other host.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use super::http::Response;
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

/// The handler of the view's server: answers from `state` and the libraries under
/// `node_modules`.
pub fn handler(
    state: Arc<Mutex<ViewState>>,
    node_modules: PathBuf,
) -> impl Fn(&str) -> Response + Send + Sync {
    move |target: &str| {
        let path = target.split(['?', '#']).next().unwrap_or("");
        match path {
            "/" | "/index.html" => {
                Response::ok("text/html; charset=utf-8", INDEX_HTML.as_bytes().to_vec())
            }
            "/app.js" => Response::ok("text/javascript; charset=utf-8", APP_JS.as_bytes().to_vec()),
            // Browsers ask for it unprompted; an empty answer keeps their consoles clean.
            "/favicon.ico" => Response::ok("image/x-icon", Vec::new()),
            "/api/state" => {
                let json = state.lock().unwrap_or_else(|e| e.into_inner()).to_json();
                Response::ok("application/json", json.to_string().into_bytes())
            }
            "/map.ply" => match state.lock().unwrap_or_else(|e| e.into_inner()).map_ply() {
                Some((version, ply)) => {
                    let mut r = Response::ok("application/octet-stream", ply);
                    r.headers.push(("X-Map-Version", version.to_string()));
                    r
                }
                None => Response::error(404, "no map yet"),
            },
            "/render.png" | "/input.png" | "/bev.png" => {
                let name = &path[1..path.len() - 4];
                match state
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .picture(name)
                {
                    Some(p) => {
                        let mut r = Response::ok("image/png", p.png);
                        r.headers.push(("X-Bin-Id", p.bin_id.to_string()));
                        r
                    }
                    None => Response::error(404, "nothing yet"),
                }
            }
            _ => library(&node_modules, path),
        }
    }
}

/// A whitelisted library file, or 404 (503 when the libraries are not installed).
fn library(node_modules: &Path, path: &str) -> Response {
    let Some((_, file)) = LIBRARIES.iter().find(|(url, _)| *url == path) else {
        return Response::error(404, "not found");
    };
    match std::fs::read(node_modules.join(file)) {
        Ok(bytes) => Response::ok("text/javascript; charset=utf-8", bytes),
        Err(e) => Response::error(
            503,
            &format!(
                "{}: {e}; install the view's libraries with `bash .ci/setup` (npm ci in view/)",
                node_modules.join(file).display()
            ),
        ),
    }
}

/// Whether every library file is present under `node_modules` (the first missing one
/// otherwise).
pub fn missing_library(node_modules: &Path) -> Option<PathBuf> {
    LIBRARIES
        .iter()
        .map(|(_, file)| node_modules.join(file))
        .find(|p| !p.is_file())
}
