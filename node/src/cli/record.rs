//! `stereosplat record`: every topic of the node (inputs and outputs) to an MCAP file.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;

use super::common::shutdown::shutdown_signal;
use super::common::zenoh_args::ZenohArgs;
use crate::clients::{self, RecordLimits};
use crate::transport::open;

/// Flags of `record`.
#[derive(Args, Clone, Debug)]
pub struct RecordArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// The MCAP file to write (replaced if it exists).
    #[arg(long)]
    out: PathBuf,
    /// Stop after this many seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Stop after this many messages.
    #[arg(long)]
    count: Option<u64>,
}

/// Records every topic of the node (inputs and outputs) until Ctrl-C, SIGTERM, `--duration`
/// or `--count`; the file is finished in every case. Prints the messages per topic.
pub fn record(args: &RecordArgs) -> Result<()> {
    let duration = args
        .duration
        .map(|s| {
            Duration::try_from_secs_f64(s)
                .ok()
                .filter(|d| !d.is_zero())
                .with_context(|| format!("--duration must be positive seconds, not {s}"))
        })
        .transpose()?;
    let limits = RecordLimits {
        duration,
        count: args.count,
    };
    let keys = args.zenoh.keys();
    create_parent(&args.out)?;
    let runtime = tokio::runtime::Runtime::new()?;
    let summary = runtime.block_on(async {
        let session = open(&args.zenoh.transport()).await?;
        eprintln!(
            "recorder ready: {} topics under {:?} -> {}",
            keys.all().len(),
            keys.namespace,
            args.out.display()
        );
        let recorded = clients::record(&session, &keys, &args.out, limits, shutdown_signal());
        anyhow::Ok(recorded.await?)
    })?;
    for (topic, count) in &summary.per_topic {
        println!("{count:>8}  {topic}");
    }
    println!(
        "{:>8}  messages in {}",
        summary.messages,
        args.out.display()
    );
    Ok(())
}

/// Creates the folder `path` will be written in.
pub(super) fn create_parent(path: &std::path::Path) -> Result<()> {
    match path.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(dir) => {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))
        }
        None => Ok(()),
    }
}
