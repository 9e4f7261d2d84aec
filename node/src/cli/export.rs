//! `stereosplat export`: a map in the formats the splat field exchanges. The input is any map
//! file (3DGS PLY, SPZ, glTF binary; told apart by content) or the node's checkpoint
//! (`global_map.ssgmap` with its journal `global_map.journal/` replayed, exported around its
//! latest bin's origin, as `run` does); the output is PLY, SPZ or glTF binary with
//! `KHR_gaussian_splatting` ([`renderer::formats`]). Prints one JSON line: what was written,
//! what was skipped or clamped, the format's position error.

use std::io::Read;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use glam::{DAffine3, DVec3};
use renderer::formats::{load_map, save_map, MapFormat};
use renderer::GaussianSet;

use crate::fusion::{local_set, AtTornTail};
use crate::store::map_files::{journal_of, restore_files, whole_map, Restored};

/// The first bytes of the node's checkpoint file.
const CHECKPOINT_MAGIC: &[u8] = b"SSGMAP";

/// Flags of `export`.
#[derive(Args, Clone, Debug)]
pub struct ExportArgs {
    /// The map to export: a PLY, SPZ or glTF binary file, or a node checkpoint
    /// (`global_map.ssgmap`).
    #[arg(long)]
    map: PathBuf,
    /// Output format: `ply`, `spz` or `glb` (docs/formats.md).
    #[arg(long, default_value_t = MapFormat::Ply)]
    format: MapFormat,
    /// Output file (default: beside the input, named `<stem>.<format>`).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// A map read for export: the Gaussians in a local frame and that frame's origin in the
/// world (a checkpoint's latest bin origin; `None` for map files, whose frame is their own).
pub struct MapInput {
    /// The Gaussians.
    pub set: GaussianSet,
    /// The world position of the set's origin, when it came from a checkpoint.
    pub origin: Option<DVec3>,
    /// What the input was (`ply`, `spz`, `glb` or `checkpoint`).
    pub kind: String,
}

/// Reads `path` as a map file (PLY, SPZ or glTF binary) or a node checkpoint.
pub fn load_input(path: &Path) -> Result<MapInput> {
    let mut head = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(CHECKPOINT_MAGIC.len() as u64).read_to_end(&mut head))
        .with_context(|| format!("reading {}", path.display()))?;
    if head == CHECKPOINT_MAGIC {
        // The base with its journal replayed: what the node had published (a record a crash
        // tore is left out, and the files are left as they are), with its paged-out tiles.
        let restored = restore_files(path, &journal_of(path), AtTornTail::Stop)
            .with_context(|| format!("reading {}", path.display()))?;
        let Some(Restored { map, replay }) = restored else {
            anyhow::bail!("{}: no such checkpoint", path.display());
        };
        if let Some(t) = replay.torn {
            eprintln!(
                "left out a record torn by a crash at the end of {} ({} bytes)",
                t.path.display(),
                t.cut_bytes
            );
        }
        let origin = map.latest_origin().unwrap_or(DVec3::ZERO);
        // Every tile: those in memory when it was saved and those paged out beside it.
        let whole = whole_map(&map, path).with_context(|| format!("reading {}", path.display()))?;
        let set = local_set(whole.iter(), DAffine3::from_translation(origin))?;
        return Ok(MapInput {
            set,
            origin: Some(origin),
            kind: "checkpoint".into(),
        });
    }
    let (format, set) = load_map(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(MapInput {
        set,
        origin: None,
        kind: format.to_string(),
    })
}

/// Exports the map and prints the JSON summary.
pub fn run(args: &ExportArgs) -> Result<()> {
    let input = load_input(&args.map)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| args.map.with_extension(args.format.extension()));
    if out == args.map {
        anyhow::bail!("--out {} is the input file; name another", out.display());
    }
    let written = save_map(&input.set, &out, args.format)
        .with_context(|| format!("writing {}", out.display()))?;
    let bytes = std::fs::metadata(&out)?.len();
    let summary = serde_json::json!({
        "input": args.map,
        "input_kind": input.kind,
        "out": out,
        "format": args.format.to_string(),
        "gaussians": written.gaussians,
        "skipped_non_finite": written.skipped_non_finite,
        "clamped": written.clamped,
        "bytes": bytes,
        "max_position_error_m": written.max_position_error_m,
        "origin": input.origin.map(|o| o.to_array()),
    });
    println!("{summary}");
    Ok(())
}
