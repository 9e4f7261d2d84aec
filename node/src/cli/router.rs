//! `stereosplat router`: a zenoh router for nodes, workers and cameras that do not reach
//! each other directly (docs/workers.md).

use anyhow::{Context, Result};
use clap::Args;

use crate::transport::open;

use super::common::shutdown::shutdown_signal;
use super::common::zenoh_args::ZenohArgs;

/// Flags of `router`.
#[derive(Args, Clone, Debug)]
pub struct RouterArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
}

/// A zenoh router (mode `router`, whatever `--mode` says) until Ctrl-C or SIGTERM: peers
/// and clients connected to it reach each other through it.
pub fn router(args: &RouterArgs) -> Result<()> {
    let mut transport = args.zenoh.transport();
    transport.mode = "router".into();
    let runtime = tokio::runtime::Runtime::new()?;
    runtime.block_on(async {
        let session = open(&transport).await.context("starting the router")?;
        eprintln!("router ready: {}", session.zid());
        shutdown_signal().await;
        session
            .close()
            .await
            .map_err(|e| anyhow::anyhow!("closing the router: {e}"))
    })
}
