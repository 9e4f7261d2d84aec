//! Writes the seed corpus of the fuzz targets (`fuzz/`, run by `scripts/fuzz.sh`): for each
//! target, a few valid inputs made by the project's own encoders ([`seeds`]).
//!
//! `cargo run --release --example fuzz_seeds -- DIR` writes `DIR/<target>/<seed>`.

mod seeds;

fn main() -> anyhow::Result<()> {
    let Some(out) = std::env::args_os().nth(1) else {
        anyhow::bail!("usage: fuzz_seeds DIR");
    };
    seeds::write_all(std::path::Path::new(&out))
}
