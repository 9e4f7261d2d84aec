//! The synchroniser's rules, one test (or a few) each: pairing, late, bounded buffers by count
//! and bytes, time jumps either way, stray frames, two sources at once.

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::*;

const MS: i64 = 1_000_000;
const S: i64 = 1_000 * MS;

type Sync = Synchronizer<u32, u32, u32>;

fn sync() -> Sync {
    Synchronizer::new(SyncConfig::default())
}

/// Sends frame `k` stamped `t` (left, right, pose, all carrying `k`), one byte each.
fn frame(s: &mut Sync, t: i64, k: u32) -> Vec<Synced<u32, u32, u32>> {
    let mut out = s.push_left(t, 1, k);
    out.extend(s.push_right(t, 1, k));
    out.extend(s.push_pose(t, 1, k));
    out
}

/// Sends frames `ks` at 10 Hz starting at `t0`; the left images of what comes out.
fn drive(s: &mut Sync, t0: i64, ks: std::ops::Range<u32>) -> Vec<u32> {
    ks.flat_map(|k| frame(s, t0 + k as i64 * 100 * MS, k))
        .map(|f| f.left)
        .collect()
}

#[test]
fn a_frame_is_emitted_when_its_last_part_arrives_in_any_order() {
    let mut s = sync();
    assert!(s.push_pose(100 * MS, 1, 3).is_empty());
    assert!(s.push_right(101 * MS, 1, 2).is_empty());
    let out = s.push_left(100 * MS, 1, 1);
    assert_eq!(out.len(), 1);
    assert_eq!(
        (out[0].stamp_ns, out[0].left, out[0].right, out[0].pose),
        (100 * MS, 1, 2, 3)
    );
    assert!(!out[0].reset);
    assert_eq!((s.pending(), s.pending_bytes()), (0, 0));
    assert_eq!(s.counters().matched, 1);
}

#[test]
fn partners_beyond_the_slop_do_not_pair() {
    let mut s = sync();
    s.push_left(100 * MS, 1, 1);
    s.push_pose(100 * MS, 1, 1);
    assert!(
        s.push_right(111 * MS, 1, 1).is_empty(),
        "11 ms apart, slop 10 ms"
    );
    assert_eq!(s.push_right(89 * MS, 1, 2).len(), 0, "11 ms before");
    assert_eq!(s.counters().conflict, 0, "22 ms apart is no conflict");
}

#[test]
fn a_missing_right_image_drops_only_its_frame() {
    let mut s = sync();
    let mut frames = Vec::new();
    for k in 0..5i64 {
        let t = k * 100 * MS;
        frames.extend(s.push_left(t, 1, k as u32));
        frames.extend(s.push_pose(t, 1, k as u32));
        if k != 2 {
            frames.extend(s.push_right(t, 1, k as u32));
        }
    }
    let lefts: Vec<u32> = frames.iter().map(|f| f.left).collect();
    assert_eq!(lefts, vec![0, 1, 3, 4]);
    let c = s.counters();
    assert_eq!(
        (c.matched, c.unmatched, c.late),
        (4, 2, 0),
        "left and pose of frame 2"
    );
    assert_eq!(s.pending(), 0);
}

#[test]
fn late_messages_are_counted_and_refused() {
    let mut s = sync();
    assert_eq!(drive(&mut s, 0, 0..2), vec![0, 1]);
    assert!(s.push_right(50 * MS, 1, 9).is_empty());
    assert!(
        s.push_left(100 * MS, 1, 9).is_empty(),
        "same stamp as the last frame"
    );
    assert!(s.push_pose(-1900 * MS, 1, 9).is_empty(), "2 s before");
    assert_eq!(s.counters().late, 3);
    assert_eq!(s.pending(), 0);
}

#[test]
fn buffers_stay_bounded_when_one_stream_is_silent() {
    let mut s = sync();
    for k in 0..1000i64 {
        s.push_left(k * 100 * MS, 1, 0);
        s.push_pose(k * 100 * MS, 1, 0);
    }
    assert_eq!(s.pending(), 2 * SyncConfig::default().capacity);
    assert_eq!(s.counters().unmatched, 2 * (1000 - 16));
}

#[test]
fn buffers_stay_within_their_byte_budget() {
    let mut s = Synchronizer::<u32, u32, u32>::new(SyncConfig {
        max_bytes_per_stream: 1000,
        ..SyncConfig::default()
    });
    // Right images of 300 bytes with no partners: three fit, each new one drops the oldest.
    for k in 0..10i64 {
        s.push_right(k * 100 * MS, 300, k as u32);
        assert!(s.pending_bytes() <= 1000, "{}", s.pending_bytes());
    }
    assert_eq!((s.pending(), s.pending_bytes()), (3, 900));
    assert_eq!(s.counters().over_budget, 7);
    // One message over the whole budget is refused; the waiting ones stay.
    s.push_left(2000 * MS, 1001, 0);
    assert_eq!((s.pending(), s.counters().over_budget), (3, 8));
    // The newest three still pair.
    for k in 7..10i64 {
        s.push_left(k * 100 * MS, 10, k as u32);
        assert_eq!(s.push_pose(k * 100 * MS, 10, k as u32).len(), 1);
    }
    assert_eq!((s.pending(), s.pending_bytes()), (0, 0));
}

#[test]
fn far_stamped_left_images_do_not_push_the_live_stream_out() {
    // The timestamp-flood attack: a full buffer of tiny left images stamped in the future; a
    // buffer that dropped its oldest *stamp* would drop every live left image from then on.
    let mut s = sync();
    assert_eq!(drive(&mut s, 0, 0..5), (0..5).collect::<Vec<_>>());
    for k in 0..16i64 {
        s.push_left(1000 * S + k * 100 * MS, 1, 99);
    }
    assert_eq!(drive(&mut s, 0, 5..40), (5..40).collect::<Vec<_>>());
    let c = s.counters();
    assert_eq!((c.matched, c.reset, c.late, c.conflict), (40, 0, 0, 0));
    // The first live left image found the buffer full and pushed out the far one received
    // first; the other 15 wait, and would go first again.
    assert_eq!((c.unmatched, s.pending()), (1, 15));
    for k in 0..3i64 {
        s.push_left(4000 * MS + k * 100 * MS, 1, 40);
    }
    assert_eq!(s.counters().unmatched, 3);
}

#[test]
fn one_frame_stamped_far_in_the_future_or_past_mid_drive_is_an_outlier() {
    for far in [1000 * S, -1000 * S, 3 * S, -3 * S] {
        let mut s = sync();
        assert_eq!(drive(&mut s, 0, 0..10), (0..10).collect::<Vec<_>>());
        assert!(frame(&mut s, 900 * MS + far, 77).is_empty(), "held");
        assert_eq!(drive(&mut s, 0, 10..30), (10..30).collect::<Vec<_>>());
        let c = s.counters();
        assert_eq!((c.matched, c.outlier, c.reset), (30, 1, 0), "{far}");
        // Two stray frames in a row are still not enough.
        frame(&mut s, 2900 * MS + far, 78);
        frame(&mut s, 3000 * MS + far, 79);
        assert_eq!(drive(&mut s, 0, 30..40), (30..40).collect::<Vec<_>>());
        assert_eq!((s.counters().outlier, s.counters().reset), (3, 0));
    }
}

#[test]
fn a_drive_replayed_again_resets_and_comes_out_whole() {
    let mut s = sync();
    assert_eq!(drive(&mut s, 0, 0..40), (0..40).collect::<Vec<_>>());
    let mut second = Vec::new();
    for k in 0..40u32 {
        second.extend(frame(&mut s, k as i64 * 100 * MS, 100 + k));
    }
    let lefts: Vec<u32> = second.iter().map(|f| f.left).collect();
    assert_eq!(lefts, (100..140).collect::<Vec<_>>());
    let resets: Vec<bool> = second.iter().map(|f| f.reset).collect();
    assert!(resets[0] && resets[1..].iter().all(|r| !r));
    let c = s.counters();
    assert_eq!((c.matched, c.reset, c.outlier, c.late), (80, 1, 0, 0));
}

#[test]
fn a_clock_jump_either_way_is_confirmed_by_three_frames() {
    for jump in [3600 * S, -3600 * S, 2100 * MS] {
        let mut s = sync();
        drive(&mut s, 0, 0..10);
        // A partial frame of the old timeline is still waiting when the clock jumps.
        s.push_left(1000 * MS, 1, 10);
        let after = drive(&mut s, jump, 11..13);
        assert!(after.is_empty(), "two frames are not a confirmed jump");
        let out = frame(&mut s, jump + 1300 * MS, 13);
        assert_eq!(
            out.iter().map(|f| (f.left, f.reset)).collect::<Vec<_>>(),
            vec![(11, true), (12, false), (13, false)]
        );
        assert_eq!(drive(&mut s, jump, 14..20), (14..20).collect::<Vec<_>>());
        let c = s.counters();
        assert_eq!((c.reset, c.outlier), (1, 0), "{jump}");
        assert_eq!(s.pending(), 0, "the old timeline's left image was dropped");
    }
}

#[test]
fn of_two_sources_on_different_clocks_the_first_keeps_the_node() {
    let mut s = sync();
    let mut out = Vec::new();
    for k in 0..50u32 {
        let t = k as i64 * 100 * MS;
        out.extend(frame(&mut s, t, k));
        out.extend(frame(&mut s, 500 * S + t, 1000 + k));
    }
    let lefts: Vec<u32> = out.iter().map(|f| f.left).collect();
    assert_eq!(lefts, (0..50).collect::<Vec<_>>());
    assert_eq!(s.counters().reset, 0);
    assert_eq!(s.counters().outlier, 49, "the last one is still held");
}

/// Three sources replaying drives with the same stamps at once, their messages interleaved at
/// random (each source in its own order left, right, pose); no frame mixes sources.
#[test]
fn sources_with_the_same_stamps_are_never_paired_across() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let mut emitted = 0;
    for _ in 0..200 {
        let mut s = sync();
        for k in 0..20u32 {
            let t = k as i64 * 100 * MS;
            // Which source sends next, as a shuffled sequence of 3 x 3 turns.
            let mut turns: Vec<u32> = (0..3).flat_map(|src| [src; 3]).collect();
            turns.shuffle(&mut rng);
            let mut next = [0usize; 3];
            for src in turns {
                let tag = src * 1000 + k;
                let out = match next[src as usize] {
                    0 => s.push_left(t, 1, tag),
                    1 => s.push_right(t, 1, tag),
                    _ => s.push_pose(t, 1, tag),
                };
                next[src as usize] += 1;
                for f in out {
                    assert!(f.left == f.right && f.right == f.pose, "{f:?}");
                    emitted += 1;
                }
            }
        }
        assert!(s.counters().conflict > 0);
    }
    // Some frames do come out: where one source sends a whole frame before another starts.
    assert!(emitted > 0);
}

#[test]
fn a_second_source_just_after_an_emitted_frame_is_a_conflict() {
    let mut s = sync();
    assert_eq!(frame(&mut s, 0, 1).len(), 1);
    // Another source 4 ms later: its left image conflicts, its right and pose are refused.
    assert!(frame(&mut s, 4 * MS, 2).is_empty());
    assert_eq!(s.counters().conflict, 3);
    assert_eq!(drive(&mut s, 0, 1..5), vec![1, 2, 3, 4]);
}

#[test]
fn stamps_at_the_ends_of_the_range_are_handled_like_any_other() {
    let mut s = sync();
    for t in [i64::MIN, i64::MAX, 0, i64::MIN + 1, i64::MAX - 1] {
        frame(&mut s, t, 1);
    }
    assert_eq!(drive(&mut s, 0, 1..10), (1..10).collect::<Vec<_>>());
    assert!(s.pending() <= 3 * SyncConfig::default().capacity);
}
