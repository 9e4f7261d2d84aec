//! `stereosplat`: the one command line of the project (every subcommand and flag: docs/node.md).

use anyhow::Result;
use clap::{Parser, Subcommand};

use node::cli::{
    bench, bench_check, bench_drive, bench_export, bench_fusion, bench_inputs, bench_keep_up,
    bench_model, bench_node, bench_pareto, bench_view, bench_workers, demo, enhancer_data, eval,
    eval_enhancer, eval_map, export, interpolate_weights, launch, logs, reconstruct, render,
    stream, synth, train, train_enhancer, view, worker,
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
    /// Render a map (PLY, SPZ or glTF binary), or a generated scene, to PNG pictures (RGB,
    /// depth, alpha).
    Render(render::RenderArgs),
    /// A map (PLY, SPZ, glTF binary or the node's checkpoint) in another format: PLY, SPZ
    /// or glTF binary with KHR_gaussian_splatting.
    Export(export::ExportArgs),
    /// Write a synthetic street, desk or room sequence in the KITTI-360 layout (training and
    /// validation seeds).
    Synth(synth::SynthArgs),
    /// Write held-out synthetic drives (seeds training never uses) for evaluation.
    SynthHeldout(synth::HeldoutArgs),
    /// The paper's evaluation protocol on a data root: table, JSON, pictures.
    Eval(eval::EvalArgs),
    /// The fused global map's own quality on a drive, swept over the fusion's settings.
    EvalMap(eval_map::EvalMapArgs),
    /// One rectified stereo pair of image files in: a PLY, depth PNGs, a render, scores.
    Reconstruct(reconstruct::ReconstructArgs),
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
    /// Start a graph of processes from a launch file; stop them together.
    Launch(launch::LaunchArgs),
    /// The streaming node: stereo frames and poses in over zenoh, Gaussian maps out.
    Run(Box<stream::RunArgs>),
    /// A worker process: takes bins from a node over zenoh and sends their maps back
    /// (docs/workers.md).
    Worker(worker::WorkerArgs),
    /// A zenoh router for nodes, workers and cameras that do not reach each other directly.
    Router(worker::RouterArgs),
    /// Replay a KITTI-360-layout sequence onto the node's input topics, or an MCAP
    /// recording onto the node's topics.
    Replay(stream::ReplayArgs),
    /// Record every topic of the node (inputs and outputs) to an MCAP file.
    Record(logs::RecordArgs),
    /// Print the node's per-bin latency live, with percentiles.
    Monitor(logs::MonitorArgs),
    /// A live page on loopback for a running node (the fused map as splats, renders,
    /// latency charts), or for a saved map with `--map`.
    View(view::ViewArgs),
    /// Benchmarks that print JSON on stdout.
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Rasterizer speed: CPU forward and backward, wgpu forward.
    Render(bench::BenchRenderArgs),
    /// A drive through the node on loopback: bins per second, stage latencies, memory.
    Node(bench_node::BenchNodeArgs),
    /// A long drive through the node at its recorded rate, its map journaled to disk: the
    /// per-bin cost as the map grows, memory, bytes written, restore time, a plot.
    Drive(bench_drive::BenchDriveArgs),
    /// The global map and its journal alone, driven by synthetic bins for hours of driving:
    /// time per bin, memory and disk use as the drive goes on.
    Fusion(bench_fusion::BenchFusionArgs),
    /// The learned reconstructor per preset: ms per stereo pair, memory, parameters.
    Model(bench_model::BenchModelArgs),
    /// The per-bin self-check on generated drives and bad pairs: scores, verdicts, cost.
    Check(bench_check::BenchCheckArgs),
    /// What a robot's camera images cost per image: JPEG and PNG decoding, pixel encodings,
    /// rectification of a raw camera.
    Inputs(bench_inputs::BenchInputsArgs),
    /// Each map format (PLY, SPZ, glTF binary) on one map: bytes, write and read time.
    Export(bench_export::BenchExportArgs),
    /// The live view's page on a large saved map in headless Chromium: frame times when it
    /// loads every tile and when it loads the tiles near its camera.
    View(bench_view::BenchViewArgs),
    /// Whether the node keeps up with a camera at KITTI-360's frame size: the latency budget
    /// `auto` against fixed operating points, bins dropped and the PSNR of what was
    /// published.
    KeepUp(bench_keep_up::BenchKeepUpArgs),
    /// How the node's bin rate grows with worker processes: a drive at KITTI-360's frame
    /// size at its recorded rate, once per number of workers.
    Workers(bench_workers::BenchWorkersArgs),
    /// Operating points from a TOML list on the same held-out bins: latency, memory,
    /// Gaussians and quality side by side, the Pareto front, a chart.
    Pareto(bench_pareto::BenchParetoArgs),
}

fn main() -> Result<()> {
    // First of all, single-threaded: glibc's allocator settings for a long-running node,
    // which it reads only as a program starts (node::service::memory).
    if let Some(e) = node::service::memory::restart_with_allocator_tunables() {
        eprintln!("warning: could not restart with the allocator's settings ({e}); going on with its defaults");
    }
    // Before any thread or wgpu/Mesa start: a private runtime folder when the environment
    // has none, so Mesa does not print its XDG_RUNTIME_DIR error lines.
    #[cfg(unix)]
    renderer::gpu::runtime_dir::ensure_runtime_dir();
    let cli = Cli::parse();
    // Mesa's shader cache inside the out folder of the commands that have one, else off;
    // `launch` leaves it to the processes it starts.
    let place = node::cli::shader_cache::place_shader_cache;
    match &cli.command {
        Command::Launch(_) => {}
        Command::Run(args) => _ = place(Some(args.out_dir())),
        Command::Demo(args) => _ = place(Some(args.out_dir())),
        _ => _ = place(None),
    }
    match cli.command {
        Command::Demo(args) => demo::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Synth(args) => synth::run(&args),
        Command::SynthHeldout(args) => synth::run_heldout(&args),
        Command::Eval(args) => eval::run(&args),
        Command::EvalMap(args) => eval_map::run(&args),
        Command::Reconstruct(args) => reconstruct::run(&args),
        Command::Train(args) => train::run(&args),
        Command::InterpolateWeights(args) => interpolate_weights::run(&args),
        Command::EnhancerData(args) => enhancer_data::run(&args),
        Command::TrainEnhancer(args) => train_enhancer::run(&args),
        Command::EvalEnhancer(args) => eval_enhancer::run(&args),
        Command::Launch(args) => launch::run(&args),
        Command::Run(args) => stream::run(&args),
        Command::Worker(args) => worker::run(&args),
        Command::Router(args) => worker::router(&args),
        Command::Replay(args) => stream::replay(&args),
        Command::Record(args) => logs::record(&args),
        Command::Monitor(args) => logs::monitor(&args),
        Command::View(args) => view::run(&args),
        Command::Bench(BenchCommand::Render(args)) => bench::run_render(&args),
        Command::Bench(BenchCommand::Node(args)) => bench_node::run(&args),
        Command::Bench(BenchCommand::Drive(args)) => bench_drive::run(&args),
        Command::Bench(BenchCommand::KeepUp(args)) => bench_keep_up::run(&args),
        Command::Bench(BenchCommand::Workers(args)) => bench_workers::run(&args),
        Command::Bench(BenchCommand::Fusion(args)) => bench_fusion::run(&args),
        Command::Bench(BenchCommand::Model(args)) => bench_model::run(&args),
        Command::Bench(BenchCommand::Check(args)) => bench_check::run(&args),
        Command::Bench(BenchCommand::Inputs(args)) => bench_inputs::run(&args),
        Command::Bench(BenchCommand::Pareto(args)) => bench_pareto::run(&args),
        Command::Bench(BenchCommand::Export(args)) => bench_export::run(&args),
        Command::Bench(BenchCommand::View(args)) => bench_view::run(&args),
    }
}
