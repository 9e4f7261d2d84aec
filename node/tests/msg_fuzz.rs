//! Malformed payloads: every truncation and thousands of seeded random mutations of valid
//! messages go through every decoder. None may panic, and none may allocate much more than
//! its input: the largest single allocation of this test binary is recorded and bounded.

mod msg_support;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use node::msg::latency::BinLatency;
use node::msg::{DecodeError, Message};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The system allocator, recording the largest single request.
struct Largest;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Largest {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Largest = Largest;

#[test]
fn every_truncation_is_a_typed_error() {
    for (name, bytes, decode) in msg_support::encoded() {
        assert!(decode(&bytes).is_ok(), "{name} decodes whole");
        for len in 0..bytes.len() {
            let err = decode(&bytes[..len]);
            // BinLatency version 4 cut to exactly version 3 (before its fusion stamp, 8 bytes
            // after 6 of padding), version 2 (before the operating point, a string of 4 + 14
            // bytes in the sample) or version 1 (40 bytes of stage stamps earlier) is an
            // older payload.
            let v3 = bytes.len() - (6 + 8);
            let v2 = v3 - (4 + 14);
            if name == BinLatency::KIND.ros_name() && [v3, v2, v2 - 40].contains(&len) {
                assert!(err.is_ok(), "{name} cut to an older version decodes");
                continue;
            }
            // The only trailing bytes a payload may lose are padding after the last field,
            // and none of the samples ends in padding.
            assert!(
                err.is_err(),
                "{name} truncated to {len} of {} decoded",
                bytes.len()
            );
            if len < 4 {
                assert_eq!(err, Err(DecodeError::NoHeader { len }));
            }
        }
    }
}

#[test]
fn random_mutations_never_panic() {
    let mut rng = ChaCha8Rng::seed_from_u64(2011);
    let (mut ok, mut failed) = (0u32, 0u32);
    let samples = msg_support::encoded();
    let cases = samples.len() as u32;
    let longest = samples.iter().map(|(_, b, _)| b.len()).max().unwrap_or(0);
    for (_, bytes, decode) in samples {
        for _ in 0..3000 {
            let mut b = bytes.clone();
            match rng.random_range(0..4) {
                // Flip a few bytes anywhere.
                0 => {
                    for _ in 0..rng.random_range(1..4) {
                        let i = rng.random_range(0..b.len());
                        b[i] = rng.random();
                    }
                }
                // Overwrite an aligned word with an extreme count.
                1 => {
                    let i = 4 + 4 * rng.random_range(0..(b.len() - 4) / 4);
                    let v: u32 = [u32::MAX, 0x8000_0000, 0x7fff_ffff, 0][rng.random_range(0..4)];
                    b[i..i + 4].copy_from_slice(&v.to_le_bytes());
                }
                // Cut at a random point and append garbage.
                2 => {
                    b.truncate(rng.random_range(0..b.len()));
                    let extra = rng.random_range(0..16);
                    b.extend((0..extra).map(|_| rng.random::<u8>()));
                }
                // Flip the byte order or the representation.
                _ => b[1] = rng.random_range(0..4),
            }
            match decode(&b) {
                Ok(()) => ok += 1,
                Err(_) => failed += 1,
            }
        }
    }
    // Both outcomes occur: the mutations reach deep fields, not just the header.
    assert_eq!(ok + failed, cases * 3000);
    assert!(ok > 1000 && failed > 1000, "ok {ok}, failed {failed}");
    // Decoded sequences hold at most one element per few input bytes; the test harness's
    // own buffers are a few KiB.
    let largest = LARGEST.load(Ordering::Relaxed);
    println!("ok {ok}, failed {failed}, largest allocation {largest} B, longest input {longest} B");
    assert!(largest < 64 * 1024, "an allocation of {largest} bytes");
}
