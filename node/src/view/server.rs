//! The live view's HTTP server: the router of [`super::routes`] (axum) served on hyper's
//! HTTP/1.1 connections over tokio, which the node already runs. axum and hyper are the
//! ecosystem's standard for this: request parsing, HEAD, status lines and connection
//! handling are theirs, tested far beyond what the page needs, and the view only says which
//! path answers what.
//!
//! The accept loop is this module's own rather than `axum::serve`, because the view must
//! stay bounded whoever connects, so a client cannot hold the node:
//! - at most [`MAX_CONNECTIONS`] connections at once: a slot is taken before a connection
//!   is accepted, so more wait in the system's queue;
//! - request heads of at most [`MAX_HEAD`] bytes (hyper answers 431 beyond);
//! - [`READ_TIMEOUT`] to send a request head, counted from the connection's start (hyper's
//!   header read timeout on tokio's timer; `axum::serve` sets no timer, so no timeout);
//! - one request per connection (`Connection: close`), so an idle browser connection does
//!   not keep a slot between the page's polls.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;

/// Connections served at once; more wait to be accepted.
pub const MAX_CONNECTIONS: usize = 32;
/// Largest request head, bytes.
pub const MAX_HEAD: usize = 16 * 1024;
/// Time a client has to send its request head.
pub const READ_TIMEOUT: Duration = Duration::from_secs(10);

/// The server's bounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Connections served at once.
    pub connections: usize,
    /// Largest request head, bytes.
    pub head_bytes: usize,
    /// Time a client has to send its request head.
    pub read_timeout: Duration,
}

impl Default for Limits {
    /// [`MAX_CONNECTIONS`], [`MAX_HEAD`], [`READ_TIMEOUT`].
    fn default() -> Self {
        Self {
            connections: MAX_CONNECTIONS,
            head_bytes: MAX_HEAD,
            read_timeout: READ_TIMEOUT,
        }
    }
}

/// Serves `router` on `listener` within `limits` until `stop` completes. Connections
/// already accepted are answered to the end on their own tasks.
pub async fn serve(
    listener: TcpListener,
    router: Router,
    limits: Limits,
    stop: impl Future<Output = ()>,
) {
    let mut http = http1::Builder::new();
    http.timer(TokioTimer::new())
        .header_read_timeout(limits.read_timeout)
        .max_header_size(limits.head_bytes)
        .keep_alive(false);
    let slots = Arc::new(Semaphore::new(limits.connections));
    tokio::pin!(stop);
    loop {
        let permit = tokio::select! {
            _ = &mut stop => return,
            permit = slots.clone().acquire_owned() => match permit {
                Ok(p) => p,
                Err(_) => return,
            },
        };
        let stream = tokio::select! {
            _ = &mut stop => return,
            accepted = listener.accept() => match accepted {
                Ok((stream, _)) => stream,
                // A connection that failed before it was accepted (reset, or the process
                // out of descriptors for a moment) is the client's loss, not the server's.
                Err(_) => continue,
            },
        };
        let connection = http.serve_connection(
            TokioIo::new(stream),
            TowerToHyperService::new(router.clone()),
        );
        tokio::spawn(async move {
            // A client that goes away mid-answer, or too slowly, is no error of ours.
            let _ = connection.await;
            drop(permit);
        });
    }
}
