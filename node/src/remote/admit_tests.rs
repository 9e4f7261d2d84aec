use glam::{DAffine3, DVec3, Vec3};
use model::kitti360::Calibration;
use model::synth::{SynthConfig, SynthSequence};

use super::*;
use crate::pipeline::operating::PointRunner;
use crate::pipeline::self_check::SelfCheck;
use crate::pipeline::worker::{run_job, Stamps, WorkerEvent};

/// A generated 136x40 bin (its right image swapped with its left when `bad`: the check
/// fails) and SGM's map of it made on the worker's path with `policy`.
fn made(policy: OnCheckFail, bad: bool) -> (Job, Output) {
    let calibration = Calibration::synthetic(136, 40);
    let rig = calibration.rig().unwrap();
    let config = SynthConfig {
        frames: 1,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    };
    let mut frame = SynthSequence::new(config, rig, calibration.cam_to_velo)
        .frame(0)
        .frame;
    frame.left_to_world =
        DAffine3::from_translation(DVec3::new(1.0e5, -2.0, 0.5)) * frame.left_to_world;
    if bad {
        std::mem::swap(&mut frame.left, &mut frame.right);
    }
    let job = Job {
        bin_id: 7,
        frame,
        rig,
        stamps: Stamps {
            source_ns: 11,
            arrival_ns: 12,
            opened_ns: 13,
            ..Stamps::default()
        },
        point: 0,
    };
    let mut runner = PointRunner::whole(model::methods::by_name("sgm").unwrap());
    let mut out = None;
    let mut take = |e| {
        if let WorkerEvent::Map(o) = e {
            out = Some(*o);
        }
    };
    run_job(
        &mut runner,
        0,
        &mut SelfCheck::new(policy),
        None,
        job.clone(),
        0,
        &mut take,
    );
    let out = out.unwrap();
    assert!(out.result.as_ref().unwrap().len() > 100, "SGM's map");
    (job, out)
}

fn rules(on_check_fail: OnCheckFail) -> Rules {
    Rules {
        on_check_fail,
        sgm_method: true,
        max_gaussians: 200_000,
    }
}

fn set_of(out: &mut Output) -> &mut GaussianSet {
    out.result.as_mut().unwrap()
}

#[test]
fn an_honest_map_is_taken_with_the_node_pose_stamps_and_check() {
    let (job, mut out) = made(OnCheckFail::Flag, false);
    assert_eq!(out.check.primary.unwrap().verdict, Verdict::Pass);
    out.stamps.source_ns = -1;
    out.stamps.arrival_ns = -2;
    out.stamps.opened_ns = -3;
    out.stamps.model_end_ns = 99;
    let want = out.check;
    let got = admit_map(&job, &rules(OnCheckFail::Flag), out).unwrap();
    assert_eq!(got.bin_to_world, job.frame.left_to_world);
    let s = got.stamps;
    assert_eq!((s.source_ns, s.arrival_ns, s.opened_ns), (11, 12, 13));
    assert_eq!(s.model_end_ns, 99, "the worker's own stages are kept");
    assert_eq!(
        got.check, want,
        "the node's check equals an honest worker's"
    );
}

#[test]
fn a_map_of_another_bin_or_pose_is_dropped() {
    let (job, out) = made(OnCheckFail::Flag, false);
    let r = rules(OnCheckFail::Flag);
    let other_bin = Output {
        bin_id: 8,
        ..clone_output(&out)
    };
    let e = admit_map(&job, &r, other_bin).unwrap_err();
    assert!(matches!(e, Rejection::Bin { got: 8, want: 7 }), "{e}");
    assert_eq!(e.counter(), "discarded/worker_pose");
    // A kilometre away, or a hair: either is not the bin the node sent.
    for shift in [1000.0, 1e-9] {
        let mut far = clone_output(&out);
        far.bin_to_world.translation.x += shift;
        let e = admit_map(&job, &r, far).unwrap_err();
        assert!(matches!(e, Rejection::Pose), "{e}");
    }
}

/// A copy of `out` (an `Output` is not `Clone`: maps move).
fn clone_output(out: &Output) -> Output {
    Output {
        bin_id: out.bin_id,
        bin_to_world: out.bin_to_world,
        result: out.result.clone(),
        check: out.check,
        render_follows: out.render_follows,
        stamps: out.stamps,
        queue_depth: out.queue_depth,
        point: out.point,
    }
}

#[test]
fn opacities_and_confidences_outside_zero_to_one_are_dropped_and_nan_is_left_to_the_fusion() {
    let (job, out) = made(OnCheckFail::Flag, false);
    let r = rules(OnCheckFail::Flag);
    for (field, value) in [
        (0, 1e30f32),
        (0, -1.0),
        (0, f32::INFINITY),
        (1, 1e30),
        (1, -f32::MIN_POSITIVE),
        (1, f32::NEG_INFINITY),
    ] {
        let mut bad = clone_output(&out);
        let set = set_of(&mut bad);
        let values = [&mut set.opacities, &mut set.confidences][field].as_mut_slice();
        values[3] = value;
        let e = admit_map(&job, &r, bad).unwrap_err();
        assert!(matches!(e, Rejection::Values { index: 3, .. }), "{e}");
        assert_eq!(e.counter(), "discarded/worker_values");
    }
    // 0 and 1 are in range; a NaN confidence is skipped by the fusion, as in the node's own
    // maps (the check ignores confidences, so the report still agrees).
    let mut edge = clone_output(&out);
    let set = set_of(&mut edge);
    set.confidences[0] = 0.0;
    set.confidences[1] = 1.0;
    set.confidences[2] = f32::NAN;
    assert!(admit_map(&job, &r, edge).is_ok());
    let mut short = clone_output(&out);
    set_of(&mut short).confidences.pop();
    let e = admit_map(&job, &r, short).unwrap_err();
    assert!(matches!(e, Rejection::Lengths(_)), "{e}");
}

#[test]
fn a_map_whose_check_the_node_does_not_reproduce_is_dropped() {
    let (job, out) = made(OnCheckFail::Flag, false);
    let r = rules(OnCheckFail::Flag);
    // The Gaussians moved 3 m deeper, the worker's passing report kept: the node's own check
    // fails the map.
    let mut moved = clone_output(&out);
    for m in &mut set_of(&mut moved).means {
        *m += Vec3::new(0.0, 0.0, 3.0);
    }
    let e = admit_map(&job, &r, moved).unwrap_err();
    assert!(matches!(e, Rejection::Check(_)), "{e}");
    assert_eq!(e.counter(), "discarded/worker_check");
    // A passing map reported as failed and flagged, or passing with another score.
    let mut flagged = clone_output(&out);
    flagged.check.action = CheckAction::Flagged;
    assert!(admit_map(&job, &r, flagged).is_err());
    let mut rescored = clone_output(&out);
    if let Some(p) = &mut rescored.check.primary {
        p.score = 1.0;
    }
    assert!(admit_map(&job, &r, rescored).is_err());
    // An SGM fallback claimed where the node's policy has none.
    let mut fallback = clone_output(&out);
    fallback.check = CheckOutcome {
        primary: Some(CheckReport {
            verdict: Verdict::Fail,
            ..out.check.primary.unwrap()
        }),
        action: CheckAction::Sgm,
        fallback: out.check.primary,
    };
    let e = admit_map(&job, &rules(OnCheckFail::Sgm), clone_output(&fallback)).unwrap_err();
    assert!(matches!(e, Rejection::Check(_)), "{e}");
    // A learned method's node takes it: SGM's map is what the node checks.
    let learned = Rules {
        sgm_method: false,
        ..rules(OnCheckFail::Sgm)
    };
    assert!(admit_map(&job, &learned, clone_output(&fallback)).is_ok());
    // The same claim with a map SGM did not make (moved) is dropped.
    for m in &mut set_of(&mut fallback).means {
        m.z += 3.0;
    }
    assert!(admit_map(&job, &learned, fallback).is_err());
}

#[test]
fn a_failed_map_is_taken_as_the_policy_says_and_lowered_opacities_are_checked_as_lowered() {
    let (job, out) = made(OnCheckFail::Flag, true);
    assert_eq!(out.check.action, CheckAction::Flagged);
    assert!(admit_map(&job, &rules(OnCheckFail::Flag), clone_output(&out)).is_ok());
    // The node lowers opacities: a flagged map is not what its worker thread would send.
    assert!(admit_map(&job, &rules(OnCheckFail::LowerOpacity), out).is_err());

    let (job, out) = made(OnCheckFail::LowerOpacity, true);
    assert_eq!(out.check.action, CheckAction::LoweredOpacity);
    let r = rules(OnCheckFail::LowerOpacity);
    let got = admit_map(&job, &r, clone_output(&out)).unwrap();
    assert_eq!(got.check.primary.unwrap().verdict, Verdict::Fail);
    // Said lowered, sent at full opacity.
    let mut full = clone_output(&out);
    for o in &mut set_of(&mut full).opacities {
        *o = (*o / LOWERED_FACTOR).min(1.0);
    }
    assert!(admit_map(&job, &r, full).is_err());
    // Said lowered, of a pair the map explains: the node's check of it passes.
    let (good_job, good) = made(OnCheckFail::Flag, false);
    let mut lowered = clone_output(&good);
    let set = set_of(&mut lowered);
    for o in set.opacities.iter_mut().chain(set.confidences.iter_mut()) {
        *o *= LOWERED_FACTOR;
    }
    lowered.check = out.check;
    assert!(admit_map(&good_job, &r, lowered).is_err());
}

#[test]
fn a_failed_reconstruction_is_taken_as_an_error() {
    let (job, mut out) = made(OnCheckFail::Flag, false);
    out.result = Err("reconstructor panicked: boom".into());
    out.check = CheckOutcome::default();
    let got = admit_map(&job, &rules(OnCheckFail::Flag), out).unwrap();
    assert!(got.result.is_err());
}

#[test]
fn a_render_of_another_bin_or_size_is_dropped() {
    let (job, _) = made(OnCheckFail::Flag, false);
    let image = model::frame::RgbImage::new(136, 40);
    let render = |bin_id, image| Rendered {
        bin_id,
        image: Ok(image),
        render_end_ns: 5,
    };
    assert!(admit_render(&job, render(7, image.clone())).is_ok());
    let e = admit_render(&job, render(6, image.clone())).unwrap_err();
    assert_eq!(e.counter(), "discarded/worker_render");
    assert!(admit_render(&job, render(7, model::frame::RgbImage::new(4000, 4000))).is_err());
    let mut short = image;
    short.data.pop();
    assert!(admit_render(&job, render(7, short)).is_err());
}

#[test]
fn the_reply_limit_follows_the_reconstructor_cap_and_the_image() {
    let fp = |method: &str, preset: &str, settings: &[&str]| Fingerprint {
        method: method.into(),
        preset: preset.into(),
        settings: settings.iter().map(|s| s.to_string()).collect(),
        weights_sha256: String::new(),
    };
    assert_eq!(max_gaussians(&fp("sgm", "", &[])), 200_000);
    assert_eq!(max_gaussians(&fp("stereosplat", "tiny", &[])), 200_000);
    assert_eq!(max_gaussians(&fp("stereosplat", "paper", &[])), 2_000_000);
    let more = fp("stereosplat", "tiny", &["max_gaussians=500000"]);
    assert_eq!(max_gaussians(&more), 500_000);
    // Fewer than SGM's: a failing map may come back as SGM's.
    let fewer = fp("stereosplat", "tiny", &["max_gaussians=10"]);
    assert_eq!(max_gaussians(&fewer), 200_000);
    assert_eq!(max_gaussians(&fp("unknown", "", &[])), 2_000_000);
    // 200,000 Gaussians of 60 bytes, or a 1408x376 render of floats.
    assert_eq!(reply_limit(200_000, 272, 72), REPLY_OVERHEAD + 12_000_000);
    assert_eq!(reply_limit(10, 1408, 376), REPLY_OVERHEAD + 1408 * 376 * 12);
    assert_eq!(reply_limit(usize::MAX, u32::MAX, u32::MAX), usize::MAX);
}
