//! `stereosplat worker`: a worker process, bins from a node over zenoh, maps back
//! (docs/workers.md).

use anyhow::Result;
use clap::Args;

use crate::pipeline::operating::PointRunner;
use crate::remote::{serve, Fingerprint, ServeConfig};

use super::common::method_args::MethodArgs;
use super::common::shutdown::shutdown_signal;
use super::common::zenoh_args::ZenohArgs;
use super::run::RenderArg;

/// Flags of `worker`.
#[derive(Args, Clone, Debug)]
pub struct WorkerArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// The reconstructor: it must be the node's (method, preset, settings and the weights'
    /// SHA-256), or the node refuses this worker.
    #[command(flatten)]
    method: MethodArgs,
    /// This worker's id, the last chunk of its key `<ns>/workers/<id>` (default:
    /// `<host>-<pid>`).
    #[arg(long)]
    id: Option<String>,
    /// Threads the reconstructor uses (sets RAYON_NUM_THREADS; default: one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Rasterizer of the renders the node asks for.
    #[arg(long, value_enum, default_value_t = RenderArg::Auto)]
    renders: RenderArg,
}

/// Answers a node's bin requests until Ctrl-C or SIGTERM, then prints what it did as JSON.
pub fn run(args: &WorkerArgs) -> Result<()> {
    if let Some(n) = args.threads {
        anyhow::ensure!(n > 0, "--threads must be at least 1");
        // candle and rayon read it when they first size their pools: before any work.
        std::env::set_var("RAYON_NUM_THREADS", n.to_string());
    }
    let spec = args.method.spec();
    let runner = PointRunner::whole(spec.build()?);
    let fingerprint = Fingerprint::of(&spec)?;
    let id = match &args.id {
        Some(id) => id.clone(),
        None => format!("{}-{}", host_name(), std::process::id()),
    };
    let config = ServeConfig {
        transport: args.zenoh.transport(),
        keys: args.zenoh.keys(),
        id,
        renders: args.renders.into(),
        threads: rayon::current_num_threads() as u32,
    };
    let threads = config.threads;
    let described = fingerprint.describe();
    let runtime = tokio::runtime::Runtime::new()?;
    let summary = runtime.block_on(serve(
        config,
        runner,
        fingerprint,
        shutdown_signal(),
        |key| eprintln!("worker ready: {key} ({described}, {threads} threads)"),
    ))?;
    println!("{}", serde_json::to_string(&summary)?);
    Ok(())
}

/// This machine's name as a key chunk (letters, digits, `-`, `_`, `.`), `host` when it
/// has none.
fn host_name() -> String {
    let name = std::fs::read_to_string("/etc/hostname").unwrap_or_default();
    let clean: String = name
        .trim()
        .chars()
        .filter(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
        .collect();
    if clean.is_empty() {
        "host".into()
    } else {
        clean
    }
}
