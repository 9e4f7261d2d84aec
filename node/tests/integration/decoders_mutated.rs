//! Every decoder of outside input (`node::untrusted_input`, the entries the fuzz targets call)
//! on its seeds and on seeded random mutations of them: bit flips, overwritten bytes,
//! truncations, insertions, repeated and swapped slices, and numbers at their extremes. None
//! may panic. A failing input is saved under the temporary folder and its path printed, so
//! `cargo fuzz run TARGET FILE` (or this test) replays it.
//!
//! This is the test suite's share of the fuzzing: a few thousand inputs per entry in seconds,
//! the same every run. The coverage-guided search over millions (`scripts/fuzz.sh`,
//! docs/fuzzing.md) runs outside the test suite.

use std::collections::{BTreeMap, BTreeSet};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::Instant;

use node::untrusted_input::ENTRIES;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::cli_support::temp_dir;
use crate::fuzz_seeds;

/// Mutated inputs per seed.
const MUTATIONS: usize = 300;

/// Mutated inputs per seed in this run: [`MUTATIONS`], or `DECODERS_MUTATIONS` from the
/// environment for a longer run by hand (the same seeded generator, run longer).
fn mutations() -> usize {
    std::env::var("DECODERS_MUTATIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(MUTATIONS)
}

/// The seeds of every entry, by entry name.
fn seeds() -> BTreeMap<String, Vec<(String, Vec<u8>)>> {
    let dir = temp_dir("decoder-seeds");
    fuzz_seeds::write_all(&dir).expect("the seeds are written");
    let mut all = BTreeMap::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let entry = entry.unwrap();
        let mut seeds: Vec<(String, Vec<u8>)> = std::fs::read_dir(entry.path())
            .unwrap()
            .map(|f| {
                let f = f.unwrap();
                let name = f.file_name().to_string_lossy().into_owned();
                (name, std::fs::read(f.path()).unwrap())
            })
            .collect();
        seeds.sort();
        all.insert(entry.file_name().to_string_lossy().into_owned(), seeds);
    }
    let _ = std::fs::remove_dir_all(&dir);
    all
}

/// One random mutation of `input` (never longer than twice it plus 64 bytes).
fn mutate(input: &[u8], rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut out = input.to_vec();
    for _ in 0..rng.random_range(1..=4) {
        let len = out.len();
        match rng.random_range(0..7) {
            0 if len > 0 => {
                let i = rng.random_range(0..len);
                out[i] ^= 1 << rng.random_range(0..8);
            }
            1 if len > 0 => {
                let i = rng.random_range(0..len);
                out[i] = [0, 0xff, 0x7f, 0x80, rng.random()][rng.random_range(0..5)];
            }
            2 => out.truncate(rng.random_range(0..=len)),
            3 => {
                let at = rng.random_range(0..=len);
                let n = rng.random_range(1..=16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.random()).collect();
                out.splice(at..at, bytes);
            }
            4 if len > 1 => {
                // A slice repeated in place (counts and lengths followed by more data).
                let a = rng.random_range(0..len);
                let b = rng.random_range(a..len.min(a + 64));
                let slice = out[a..=b].to_vec();
                out.splice(a..a, slice);
            }
            5 if len >= 8 => {
                // A little-endian u32 or u64 at its extremes (lengths, counts, sizes).
                let i = rng.random_range(0..len - 7);
                let value: u64 = [0, 1, u32::MAX as u64, u64::MAX, 1 << 31][rng.random_range(0..5)];
                let width = if rng.random() { 4 } else { 8 };
                out[i..i + width].copy_from_slice(&value.to_le_bytes()[..width]);
            }
            6 if len > 1 => {
                let (a, b) = (rng.random_range(0..len), rng.random_range(0..len));
                out.swap(a, b);
            }
            _ => {}
        }
    }
    out
}

#[test]
fn every_decoder_survives_its_seeds_and_their_mutations() {
    let seeds = seeds();
    assert_eq!(
        seeds.keys().map(String::as_str).collect::<BTreeSet<_>>(),
        ENTRIES
            .iter()
            .map(|&(name, _)| name)
            .collect::<BTreeSet<_>>(),
        "a seed folder per entry and an entry per seed folder"
    );
    let mutations = mutations();
    let mut tried = 0;
    for &(name, entry) in ENTRIES {
        let started = Instant::now();
        let inputs = seeds
            .get(name)
            .unwrap_or_else(|| panic!("no seeds for {name}"));
        assert!(!inputs.is_empty(), "{name}: seeds");
        let mut rng = ChaCha8Rng::seed_from_u64(0x5eed ^ name.len() as u64);
        for (seed_name, seed) in inputs {
            for i in 0..=mutations {
                let input = if i == 0 {
                    seed.clone()
                } else {
                    mutate(seed, &mut rng)
                };
                if catch_unwind(AssertUnwindSafe(|| entry(&input))).is_err() {
                    let path = std::env::temp_dir().join(format!("crash-{name}-{seed_name}-{i}"));
                    std::fs::write(&path, &input).unwrap();
                    panic!(
                        "{name} panicked on a mutation of seed {seed_name}: {}",
                        path.display()
                    );
                }
                tried += 1;
            }
        }
        let n = inputs.len() * (mutations + 1);
        eprintln!(
            "{name}: {n} inputs in {:.2} s",
            started.elapsed().as_secs_f64()
        );
    }
    assert!(tried > 14 * mutations, "{tried} inputs");
}
