//! The flags that pick a reconstructor (`--method`, `--preset`, `--weights`, `--set`), shared
//! by the commands that run one on files (`eval`, `reconstruct`) and those that run the node
//! (`run`, `demo`, `bench node`).

use std::path::PathBuf;

use clap::Args;
use model::methods::{MethodError, MethodSpec};
use model::reconstruct::Reconstructor;

use crate::service::NodeConfig;

/// Which reconstructor, with which preset, weights and settings.
#[derive(Args, Clone, Debug)]
#[command(next_help_heading = "Reconstructor")]
pub struct MethodArgs {
    /// The reconstructor (see `model::methods`).
    #[arg(long, default_value = model::methods::DEFAULT)]
    pub method: String,
    /// Network preset of a learned method: tiny (default), tiny-plus or tiny-3d, whose weights
    /// ship in the binary; small and paper ship none and need --weights (train them with
    /// `stereosplat research train`).
    #[arg(long)]
    pub preset: Option<String>,
    /// Weights of a learned method (default: the preset's shipped file).
    #[arg(long)]
    pub weights: Option<PathBuf>,
    /// Change a preset setting of a learned method, or a setting of `sgm`, `KEY=VALUE`
    /// (repeatable), e.g. `--set pair_fusion_margin=null`, `--method sgm --set median=false`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub settings: Vec<String>,
}

impl MethodArgs {
    /// The reconstructor these flags name, as one value.
    pub fn spec(&self) -> MethodSpec {
        MethodSpec {
            method: self.method.clone(),
            preset: self.preset.clone(),
            weights: self.weights.clone(),
            settings: self.settings.clone(),
        }
    }

    /// The reconstructor these flags name ([`MethodSpec::build`]).
    pub fn build(&self) -> Result<Box<dyn Reconstructor + Send>, MethodError> {
        self.spec().build()
    }

    /// `config` with the node's reconstructor set to what these flags name.
    pub fn node_config(&self, config: NodeConfig) -> NodeConfig {
        NodeConfig {
            method: self.spec(),
            ..config
        }
    }
}
