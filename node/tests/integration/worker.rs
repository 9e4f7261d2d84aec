//! The worker thread with the real SGM reconstructor on generated frames: bins come back in
//! order with maps in the bin frame, a burst beyond the queue drops the oldest waiting bins
//! (counted) without blocking the caller, and a reconstructor panic is reported on its bin
//! while the worker goes on.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use model::kitti360::Calibration;
use model::reconstruct::{ReconstructError, Reconstructor, StereoView};
use model::synth::{SynthConfig, SynthSequence};
use node::pipeline::self_check::OnCheckFail;
use node::pipeline::worker::{
    now_ns, Job, Output, RenderWith, Stamps, Submitted, Worker, WorkerEvent,
};
use renderer::GaussianSet;

fn jobs(n: usize) -> Vec<Job> {
    let calibration = Calibration::synthetic(136, 40);
    let rig = calibration.rig().unwrap();
    let config = SynthConfig {
        frames: n as u32,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    };
    let seq = SynthSequence::new(config, rig, calibration.cam_to_velo);
    (0..n)
        .map(|i| Job {
            bin_id: i as u64,
            frame: seq.frame(i).frame,
            rig,
            stamps: Stamps {
                arrival_ns: now_ns(),
                ..Stamps::default()
            },
            point: 0,
        })
        .collect()
}

fn collect<T>(rx: &mpsc::Receiver<T>, n: usize) -> Vec<T> {
    (0..n)
        .map(|_| rx.recv_timeout(Duration::from_secs(60)).expect("an output"))
        .collect()
}

/// Sends the maps on, ignoring renders (for workers with renders off).
fn maps_to(tx: mpsc::Sender<Output>) -> impl FnMut(WorkerEvent) + Send + 'static {
    move |e| {
        if let WorkerEvent::Map(o) = e {
            tx.send(*o).unwrap();
        }
    }
}

#[test]
fn bins_come_back_in_order_with_maps_and_stamps() {
    let (tx, rx) = mpsc::channel();
    let sgm = model::methods::by_name("sgm").unwrap();
    let worker = Worker::spawn(sgm, RenderWith::Cpu, 4, OnCheckFail::Flag, move |o| {
        tx.send(o).unwrap()
    });
    let input = jobs(3);
    for job in input.clone() {
        assert_eq!(worker.submit(job), Submitted::Queued);
    }
    // Each map, then its render.
    let events = collect(&rx, 6);
    for (pair, job) in events.chunks(2).zip(&input) {
        let (WorkerEvent::Map(o), WorkerEvent::Render(r)) = (&pair[0], &pair[1]) else {
            panic!("a map, then its render: {pair:?}");
        };
        assert_eq!((o.bin_id, r.bin_id), (job.bin_id, job.bin_id));
        assert!(o.render_follows);
        assert_eq!(o.bin_to_world, job.frame.left_to_world);
        let set = o.result.as_ref().unwrap();
        assert!(set.len() > 1000, "{} Gaussians", set.len());
        // Bin frame = first left camera: the map lies in front of it.
        let mean_z: f32 = set.means.iter().map(|m| m.z).sum::<f32>() / set.len() as f32;
        assert!(mean_z > 2.0, "{mean_z}");
        let s = o.stamps;
        assert!(s.arrival_ns <= s.model_start_ns && s.model_start_ns <= s.model_end_ns);
        assert!(s.model_end_ns <= r.render_end_ns);
        // The render from the input view looks like the input image.
        let render = r.image.as_ref().unwrap();
        let left = &job.frame.left;
        assert_eq!((render.width, render.height), (left.width, left.height));
        let psnr = model::metrics::psnr(render, left).unwrap();
        assert!(psnr > 15.0, "render vs input: PSNR {psnr:.2} dB");
    }
    assert_eq!(worker.drops(), 0);
    worker.shutdown();
}

#[test]
fn a_burst_drops_the_oldest_waiting_bins_without_blocking() {
    let (tx, rx) = mpsc::channel();
    let worker = Worker::spawn(
        model::methods::by_name("sgm").unwrap(),
        RenderWith::Off,
        2,
        OnCheckFail::Flag,
        maps_to(tx),
    );
    let input = jobs(2);
    let start = Instant::now();
    let mut dropped = 0;
    for k in 0..20u64 {
        let mut job = input[(k % 2) as usize].clone();
        job.bin_id = k;
        dropped += (worker.submit(job) == Submitted::DroppedOldest) as u64;
    }
    // Twenty submissions of a job that takes milliseconds each return at once.
    assert!(start.elapsed() < Duration::from_secs(5));
    assert!(dropped > 0);
    assert_eq!(worker.drops(), dropped);
    worker.shutdown();
    let out: Vec<Output> = rx.try_iter().collect();
    assert_eq!(
        out.len() as u64 + dropped,
        20,
        "every bin is either done or counted"
    );
    // Keep newest: the last bin submitted is always among those done.
    assert_eq!(out.last().unwrap().bin_id, 19);
    assert!(out.windows(2).all(|w| w[0].bin_id < w[1].bin_id));
}

/// A test double: SGM cannot be made to panic, and the recovery path needs a panic.
struct PanicsOnSecond {
    calls: usize,
}

impl Reconstructor for PanicsOnSecond {
    fn name(&self) -> &str {
        "panics-on-second"
    }

    fn reconstruct(&mut self, _: &[StereoView<'_>]) -> Result<GaussianSet, ReconstructError> {
        self.calls += 1;
        if self.calls == 2 {
            panic!("planted failure");
        }
        Ok(GaussianSet::default())
    }
}

#[test]
fn a_panic_is_reported_on_its_bin_and_the_worker_goes_on() {
    let (tx, rx) = mpsc::channel();
    let worker = Worker::spawn(
        Box::new(PanicsOnSecond { calls: 0 }),
        RenderWith::Off,
        4,
        OnCheckFail::Flag,
        maps_to(tx),
    );
    for job in jobs(3) {
        worker.submit(job);
    }
    let out = collect(&rx, 3);
    assert!(out[0].result.is_ok());
    let err = out[1].result.as_ref().unwrap_err();
    assert!(err.contains("planted failure"), "{err}");
    assert!(out[2].result.is_ok());
    worker.shutdown();
}

#[test]
fn the_progressive_pass_splits_the_model_time_into_its_stages() {
    let (tx, rx) = mpsc::channel();
    let settings = ["progressive=true".to_string(), "enhancer=false".to_string()];
    let plus = model::methods::build("stereosplat", None, None, &settings).unwrap();
    let worker = Worker::spawn(plus, RenderWith::Cpu, 4, OnCheckFail::Flag, maps_to(tx));
    worker.submit(jobs(1).remove(0));
    let o = collect(&rx, 1).remove(0);
    assert!(o.result.as_ref().unwrap().len() > 1000);
    let s = o.stamps;
    // G_base, pseudo render, enhance (off: no time), plus, fuse: in order within the model.
    let ends = s.stage_end_ns;
    assert!(s.model_start_ns < ends[0], "{s:?}");
    assert!(ends.windows(2).all(|w| w[0] <= w[1]), "{s:?}");
    assert_eq!(ends[1], ends[2], "the enhancer is off");
    assert!(ends[4] <= s.model_end_ns, "{s:?}");
    worker.shutdown();
}
