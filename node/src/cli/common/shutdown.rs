//! The stop request of long-running subcommands (node, record, monitor): Ctrl-C or SIGTERM.

use std::future::pending;

use tokio::signal::unix::{signal, SignalKind};

/// Completes at the first Ctrl-C (SIGINT) or SIGTERM. A signal whose handler cannot be
/// installed is not waited for (its default action, ending the process, stays).
pub async fn shutdown_signal() {
    let interrupt = async {
        if tokio::signal::ctrl_c().await.is_err() {
            pending::<()>().await;
        }
    };
    let terminate = async {
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                term.recv().await;
            }
            Err(_) => pending::<()>().await,
        }
    };
    tokio::select! {
        _ = interrupt => {}
        _ = terminate => {}
    }
}
