use std::time::{Duration, Instant};

use glam::DAffine3;
use model::frame::{RgbImage, StereoFrame, StereoRig};
use renderer::{GaussianSet, Intrinsics};

use super::*;
use crate::pipeline::worker::Stamps;

fn job(bin_id: u64) -> Job {
    let image = RgbImage::new(4, 2);
    Job {
        bin_id,
        frame: StereoFrame {
            index: bin_id as u32,
            left: image.clone(),
            right: image,
            left_to_world: DAffine3::IDENTITY,
        },
        rig: StereoRig {
            intrinsics: Intrinsics::from_hfov(4, 2, 90.0),
            baseline: 0.5,
        },
        stamps: Stamps::default(),
        point: 0,
    }
}

fn map(bin_id: u64, render_follows: bool) -> WorkerEvent {
    WorkerEvent::Map(Box::new(Output {
        bin_id,
        bin_to_world: DAffine3::IDENTITY,
        result: Ok(GaussianSet::with_capacity(0)),
        check: CheckOutcome::default(),
        render_follows,
        stamps: Stamps::default(),
        queue_depth: 0,
        point: 0,
    }))
}

fn render(bin_id: u64) -> WorkerEvent {
    WorkerEvent::Render(Rendered {
        bin_id,
        image: Ok(RgbImage::new(1, 1)),
        render_end_ns: 0,
    })
}

/// What was released, as (bin, 'm' for a map or 'r' for a render).
fn released(d: &mut Dispatch) -> Vec<(u64, char)> {
    d.released()
        .iter()
        .map(|e| match e {
            WorkerEvent::Map(o) => (o.bin_id, 'm'),
            WorkerEvent::Render(r) => (r.bin_id, 'r'),
        })
        .collect()
}

fn remote(id: &str) -> Slot {
    Slot::Remote(id.into())
}

fn bins(a: &[Assignment]) -> Vec<(Slot, u64, u32)> {
    a.iter()
        .map(|a| (a.slot.clone(), a.job.bin_id, a.attempt))
        .collect()
}

#[test]
fn a_full_queue_drops_its_oldest_waiting_bin() {
    let mut d = Dispatch::new(2, true);
    assert_eq!(d.submit(job(0)), Submitted::Queued);
    assert_eq!(d.submit(job(1)), Submitted::Queued);
    assert_eq!(d.submit(job(2)), Submitted::DroppedOldest);
    assert_eq!(d.drops(), 1);
    let now = Instant::now();
    assert_eq!(bins(&d.assign(now)), vec![(Slot::Local, 1, 0)]);
    // The thread is busy: nothing more goes out.
    assert!(d.assign(now).is_empty());
    assert_eq!(d.waiting(), 1);
}

#[test]
fn workers_take_bins_processes_first_and_maps_are_released_in_bin_order() {
    let mut d = Dispatch::new(8, true);
    d.joined("a");
    d.joined("b");
    for bin in 0..4 {
        d.submit(job(bin));
    }
    let now = Instant::now();
    assert_eq!(
        bins(&d.assign(now)),
        vec![
            (remote("a"), 0, 0),
            (remote("b"), 1, 0),
            (Slot::Local, 2, 0)
        ]
    );
    // Bin 2 finishes first, then 1: neither goes out before bin 0.
    assert_eq!(d.event(&Slot::Local, None, map(2, true)), Answer::Accepted);
    assert_eq!(d.event(&Slot::Local, None, render(2)), Answer::Accepted);
    assert_eq!(
        d.event(&remote("b"), Some(0), map(1, false)),
        Answer::Accepted
    );
    assert!(released(&mut d).is_empty());
    // b, done, takes bin 3 before the thread does.
    assert_eq!(bins(&d.assign(now)), vec![(remote("b"), 3, 0)]);
    assert_eq!(
        d.event(&remote("a"), Some(0), map(0, true)),
        Answer::Accepted
    );
    assert_eq!(
        released(&mut d),
        vec![(0, 'm'), (1, 'm'), (2, 'm'), (2, 'r')]
    );
    // Bin 0's render comes after its map was released: it goes straight out.
    assert_eq!(d.event(&remote("a"), Some(0), render(0)), Answer::Accepted);
    assert_eq!(released(&mut d), vec![(0, 'r')]);
    d.answered(&remote("a"), 0, 0);
    d.answered(&remote("b"), 1, 0);
    assert_eq!(
        d.event(&remote("b"), Some(0), map(3, false)),
        Answer::Accepted
    );
    assert_eq!(released(&mut d), vec![(3, 'm')]);
    assert!(d.idle());
}

#[test]
fn a_bin_of_a_worker_that_left_goes_to_another_and_is_published_once() {
    let mut d = Dispatch::new(8, false);
    d.joined("a");
    d.submit(job(0));
    let now = Instant::now();
    assert_eq!(bins(&d.assign(now)), vec![(remote("a"), 0, 0)]);
    assert!(d.left("a"));
    assert!(!d.left("a"), "a worker leaves once");
    assert!(d.assign(now).is_empty(), "no worker left");
    d.joined("b");
    assert_eq!(bins(&d.assign(now)), vec![(remote("b"), 0, 1)]);
    assert_eq!(
        d.event(&remote("b"), Some(1), map(0, false)),
        Answer::Accepted
    );
    assert_eq!(released(&mut d), vec![(0, 'm')]);
    assert_eq!(d.reassigned(), 1);
    assert!(d.idle());
}

#[test]
fn a_stalled_worker_keeps_no_new_bin_and_its_late_map_is_discarded() {
    let mut d = Dispatch::new(8, false);
    d.joined("a");
    d.joined("b");
    d.submit(job(0));
    let t0 = Instant::now();
    assert_eq!(bins(&d.assign(t0)), vec![(remote("a"), 0, 0)]);
    let timeout = Duration::from_secs(1);
    assert!(d
        .stalled(t0 + Duration::from_millis(900), timeout)
        .is_empty());
    let t1 = t0 + Duration::from_millis(1100);
    assert_eq!(d.stalled(t1, timeout), vec!["a".to_string()]);
    d.submit(job(1));
    // Bin 0 goes again first, to b; a, still holding it as far as anyone knows, gets none.
    assert_eq!(bins(&d.assign(t1)), vec![(remote("b"), 0, 1)]);
    assert_eq!(d.event(&remote("a"), Some(0), map(0, true)), Answer::Late);
    assert_eq!(d.event(&remote("a"), Some(0), render(0)), Answer::Late);
    assert_eq!(d.late(), 1);
    assert!(released(&mut d).is_empty());
    d.answered(&remote("a"), 0, 0);
    assert_eq!(bins(&d.assign(t1)), vec![(remote("a"), 1, 0)]);
    assert_eq!(
        d.event(&remote("b"), Some(1), map(0, false)),
        Answer::Accepted
    );
    assert_eq!(
        d.event(&remote("a"), Some(0), map(1, false)),
        Answer::Accepted
    );
    assert_eq!(released(&mut d), vec![(0, 'm'), (1, 'm')]);
}

#[test]
fn a_bin_no_worker_answers_is_published_as_failed_after_its_last_attempt() {
    let mut d = Dispatch::new(8, false);
    d.joined("a");
    d.submit(job(7));
    let now = Instant::now();
    for attempt in 0..MAX_ATTEMPTS {
        assert_eq!(bins(&d.assign(now)), vec![(remote("a"), 7, attempt)]);
        // The query ends with an error reply and no map.
        d.answered(&remote("a"), 7, attempt);
    }
    let out = d.released();
    assert_eq!(out.len(), 1);
    let WorkerEvent::Map(o) = &out[0] else {
        panic!("a map")
    };
    assert_eq!(o.bin_id, 7);
    assert_eq!(
        o.result.as_ref().err().map(String::as_str),
        Some("no worker answered in 3 attempts")
    );
    assert!(d.assign(now).is_empty());
    assert!(d.idle());
}

#[test]
fn a_worker_that_leaves_after_its_map_finishes_the_bin_without_its_render() {
    let mut d = Dispatch::new(8, false);
    d.joined("a");
    d.submit(job(0));
    let _ = d.assign(Instant::now());
    assert_eq!(
        d.event(&remote("a"), Some(0), map(0, true)),
        Answer::Accepted
    );
    assert_eq!(released(&mut d), vec![(0, 'm')]);
    d.left("a");
    let out = d.released();
    assert!(
        matches!(&out[..], [WorkerEvent::Render(r)] if r.bin_id == 0 && r.image.is_err()),
        "{out:?}"
    );
    assert_eq!(d.reassigned(), 0, "a bin with its map is not made again");
    assert!(d.idle());
}

#[test]
fn a_dropped_bin_does_not_hold_back_the_bins_after_it() {
    let mut d = Dispatch::new(1, false);
    d.joined("a");
    d.submit(job(0));
    let now = Instant::now();
    let _ = d.assign(now);
    d.submit(job(1));
    d.submit(job(2)); // drops 1
    assert_eq!(
        d.event(&remote("a"), Some(0), map(0, false)),
        Answer::Accepted
    );
    d.answered(&remote("a"), 0, 0);
    assert_eq!(bins(&d.assign(now)), vec![(remote("a"), 2, 0)]);
    assert_eq!(
        d.event(&remote("a"), Some(0), map(2, false)),
        Answer::Accepted
    );
    assert_eq!(released(&mut d), vec![(0, 'm'), (2, 'm')]);
    assert_eq!(d.unfinished(), 0);
}

#[test]
fn a_bin_whose_worker_is_expelled_goes_out_again_without_using_an_attempt() {
    let mut d = Dispatch::new(4, false);
    for id in ["a", "b", "c", "d", "e", "f"] {
        d.joined(id);
    }
    d.submit(job(0));
    let now = Instant::now();
    // Three workers in turn send replies the node drops: the bin is still given out.
    for (id, attempt) in [("a", 0), ("b", 1), ("c", 2)] {
        assert_eq!(bins(&d.assign(now)), vec![(remote(id), 0, attempt)]);
        assert!(d.expel(id));
        assert!(!d.expel(id), "once");
    }
    assert_eq!(d.workers(), 3);
    // Then three hand-outs that count: the third is the last.
    for attempt in [3, 4, 5] {
        assert!(d.released().is_empty());
        assert_eq!(bins(&d.assign(now)), vec![(remote("d"), 0, attempt)]);
        d.answered(&remote("d"), 0, attempt);
    }
    let WorkerEvent::Map(failed) = d.released().remove(0) else {
        panic!("a map")
    };
    assert!(failed.result.unwrap_err().contains("no worker answered"));
    assert_eq!(d.reassigned(), 6);
    // An expelled worker's late map is discarded.
    assert_eq!(d.event(&remote("a"), Some(0), map(0, false)), Answer::Late);
}
