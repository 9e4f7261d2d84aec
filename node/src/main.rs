//! `stereosplat`: the one command line of the project (every subcommand and flag: docs/node.md).

use anyhow::Result;
use clap::{Parser, Subcommand};

use node::bench;
use node::cli::{
    demo, export, launch, monitor, reconstruct, record, render, replay, router, run, view, worker,
};
use node::research::{
    enhancer_data, eval, eval_enhancer, eval_map, interpolate_weights, synth, train, train_enhancer,
};

/// StereoSplat: stereo frames in, 3D Gaussian splatting maps out.
#[derive(Parser)]
#[command(name = "stereosplat", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The main job: a generated drive replayed through the node on loopback; per-bin maps,
    /// the fused global map and a latency summary in one folder.
    Demo(demo::DemoArgs),
    /// The streaming node: stereo frames and poses in over zenoh, Gaussian maps out.
    Run(Box<run::RunArgs>),
    /// Replay a KITTI-360-layout sequence onto the node's input topics, or an MCAP
    /// recording onto the node's topics.
    Replay(replay::ReplayArgs),
    /// Record every topic of the node (inputs and outputs) to an MCAP file.
    Record(record::RecordArgs),
    /// Print the node's per-bin latency live, with percentiles.
    Monitor(monitor::MonitorArgs),
    /// A live page on loopback for a running node (the fused map as splats, renders,
    /// latency charts), or for a saved map with `--map`.
    View(view::ViewArgs),
    /// One rectified stereo pair of image files in: a PLY, depth PNGs, a render, scores.
    Reconstruct(reconstruct::ReconstructArgs),
    /// A map (PLY, SPZ, glTF binary or the node's checkpoint) in another format: PLY, SPZ
    /// or glTF binary with KHR_gaussian_splatting.
    Export(export::ExportArgs),
    /// Render a map (PLY, SPZ or glTF binary), or a generated scene, to PNG pictures (RGB,
    /// depth, alpha).
    Render(render::RenderArgs),
    /// Start a graph of processes from a launch file; stop them together.
    Launch(launch::LaunchArgs),
    /// A worker process: takes bins from a node over zenoh and sends their maps back
    /// (docs/workers.md).
    Worker(worker::WorkerArgs),
    /// A zenoh router for nodes, workers and cameras that do not reach each other directly.
    Router(router::RouterArgs),
    /// Benchmarks that print JSON on stdout.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Generated data, training and evaluation: how the shipped weights are made and scored.
    #[command(subcommand)]
    Research(ResearchCommand),
}

#[derive(Subcommand)]
enum ResearchCommand {
    /// Write a synthetic street, desk or room sequence in the KITTI-360 layout (training and
    /// validation seeds).
    Synth(synth::SynthArgs),
    /// Write held-out synthetic drives (seeds training never uses) for evaluation.
    SynthHeldout(synth::HeldoutArgs),
    /// The paper's evaluation protocol on a data root: table, JSON, pictures.
    Eval(eval::EvalArgs),
    /// The fused global map's own quality on a drive, swept over the fusion's settings.
    EvalMap(eval_map::EvalMapArgs),
    /// Train a network preset: checkpoints, resume, CSV log, loss curve, safetensors.
    Train(train::TrainArgs),
    /// Blend two trained weight files of one network: `(1 - t) * from + t * to` per tensor.
    InterpolateWeights(interpolate_weights::InterpolateWeightsArgs),
    /// Training pairs for the one-step enhancer: StereoSplat's renders of the bins' other
    /// frames, with alpha and confidence, against the true images.
    EnhancerData(enhancer_data::EnhancerDataArgs),
    /// Train the one-step enhancer on pairs from `enhancer-data`: checkpoints, resume, CSV
    /// log, loss curve, safetensors.
    TrainEnhancer(train_enhancer::TrainEnhancerArgs),
    /// Score raw against enhanced renders on held-out pairs: PSNR, unseen-region PSNR,
    /// LPIPS, as JSON.
    EvalEnhancer(eval_enhancer::EvalEnhancerArgs),
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Rasterizer speed: CPU forward and backward, wgpu forward.
    Render(bench::render::BenchRenderArgs),
    /// A drive through the node on loopback: bins per second, stage latencies, memory.
    Node(bench::node::BenchNodeArgs),
    /// A long drive through the node at its recorded rate, its map journaled to disk: the
    /// per-bin cost as the map grows, memory, bytes written, restore time, a plot.
    Drive(bench::drive::BenchDriveArgs),
    /// The global map and its journal alone, driven by synthetic bins for hours of driving:
    /// time per bin, memory and disk use as the drive goes on.
    Fusion(bench::fusion::BenchFusionArgs),
    /// The learned reconstructor per preset: ms per stereo pair, memory, parameters.
    Model(bench::model::BenchModelArgs),
    /// The per-bin self-check on generated drives and bad pairs: scores, verdicts, cost.
    Check(bench::check::BenchCheckArgs),
    /// What a robot's camera images cost per image: JPEG and PNG decoding, pixel encodings,
    /// rectification of a raw camera.
    Inputs(bench::inputs::BenchInputsArgs),
    /// Each map format (PLY, SPZ, glTF binary) on one map: bytes, write and read time.
    Export(bench::export::BenchExportArgs),
    /// The live view's page on a large saved map in headless Chromium: frame times when it
    /// loads every tile and when it loads the tiles near its camera.
    View(bench::view::BenchViewArgs),
    /// Whether the node keeps up with a camera at KITTI-360's frame size: the latency budget
    /// `auto` against fixed operating points, bins dropped and the PSNR of what was
    /// published.
    KeepUp(bench::keep_up::BenchKeepUpArgs),
    /// How the node's bin rate grows with worker processes: a drive at KITTI-360's frame
    /// size at its recorded rate, once per number of workers.
    Workers(bench::workers::BenchWorkersArgs),
    /// Operating points from a TOML list on the same held-out bins: latency, memory,
    /// Gaussians and quality side by side, the Pareto front, a chart.
    Pareto(bench::pareto::BenchParetoArgs),
}

fn main() -> Result<()> {
    // First of all, single-threaded: glibc's allocator settings for a long-running node,
    // which it reads only as a program starts (node::memory).
    if let Some(e) = node::memory::restart_with_allocator_tunables() {
        eprintln!("warning: could not restart with the allocator's settings ({e}); going on with its defaults");
    }
    // Before any thread or wgpu/Mesa start: a private runtime folder when the environment
    // has none, so Mesa does not print its XDG_RUNTIME_DIR error lines.
    #[cfg(unix)]
    renderer::gpu::runtime_dir::ensure_runtime_dir();
    let cli = Cli::parse();
    // Mesa's shader cache inside the out folder of the commands that have one, else off;
    // `launch` leaves it to the processes it starts.
    let place = node::cli::common::shader_cache::place_shader_cache;
    match &cli.command {
        Command::Launch(_) => {}
        Command::Run(args) => _ = place(Some(args.out_dir())),
        Command::Demo(args) => _ = place(Some(args.out_dir())),
        _ => _ = place(None),
    }
    match cli.command {
        Command::Demo(args) => demo::run(&args),
        Command::Run(args) => run::run(&args),
        Command::Replay(args) => replay::replay(&args),
        Command::Record(args) => record::record(&args),
        Command::Monitor(args) => monitor::monitor(&args),
        Command::View(args) => view::run(&args),
        Command::Reconstruct(args) => reconstruct::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Launch(args) => launch::run(&args),
        Command::Worker(args) => worker::run(&args),
        Command::Router(args) => router::router(&args),
        Command::Bench(command) => run_bench(command),
        Command::Research(command) => run_research(command),
    }
}

fn run_bench(command: BenchCommand) -> Result<()> {
    match command {
        BenchCommand::Render(args) => bench::render::run(&args),
        BenchCommand::Node(args) => bench::node::run(&args),
        BenchCommand::Drive(args) => bench::drive::run(&args),
        BenchCommand::KeepUp(args) => bench::keep_up::run(&args),
        BenchCommand::Workers(args) => bench::workers::run(&args),
        BenchCommand::Fusion(args) => bench::fusion::run(&args),
        BenchCommand::Model(args) => bench::model::run(&args),
        BenchCommand::Check(args) => bench::check::run(&args),
        BenchCommand::Inputs(args) => bench::inputs::run(&args),
        BenchCommand::Pareto(args) => bench::pareto::run(&args),
        BenchCommand::Export(args) => bench::export::run(&args),
        BenchCommand::View(args) => bench::view::run(&args),
    }
}

fn run_research(command: ResearchCommand) -> Result<()> {
    match command {
        ResearchCommand::Synth(args) => synth::run(&args),
        ResearchCommand::SynthHeldout(args) => synth::run_heldout(&args),
        ResearchCommand::Eval(args) => eval::run(&args),
        ResearchCommand::EvalMap(args) => eval_map::run(&args),
        ResearchCommand::Train(args) => train::run(&args),
        ResearchCommand::InterpolateWeights(args) => interpolate_weights::run(&args),
        ResearchCommand::EnhancerData(args) => enhancer_data::run(&args),
        ResearchCommand::TrainEnhancer(args) => train_enhancer::run(&args),
        ResearchCommand::EvalEnhancer(args) => eval_enhancer::run(&args),
    }
}
