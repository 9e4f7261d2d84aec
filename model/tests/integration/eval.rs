//! The evaluation protocol on a generated drive, with bad data planted in it: each case is
//! either skipped and counted (the bin, with its reason) or scored without the broken part,
//! and the run goes on.

use std::path::{Path, PathBuf};

use model::baseline::{SgmConfig, SgmReconstructor};
use model::eval::{evaluate, BinReport, EvalConfig, Raster, SkippedBin};
use model::frame::Side;
use model::generate::{sequence_name, write_synthetic};
use model::kitti360::{layout, Sequence};
use model::lpips::Lpips;
use model::synth::SynthConfig;

const SEED: u64 = 7;

/// A fresh 30-frame drive at 136x40 under a temp root.
fn drive(case: &str) -> (PathBuf, String) {
    let root = std::env::temp_dir().join(format!("stereosplat-eval-{case}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let config = SynthConfig {
        seed: SEED,
        frames: 30,
        width: 136,
        height: 40,
        ..SynthConfig::default()
    };
    let name = write_synthetic(&root, &config, &mut |_, _| {}).unwrap();
    assert_eq!(name, sequence_name(SEED));
    (root, name)
}

/// Evaluates the baseline on the drive, with LPIPS when `lpips` is given.
fn run(
    root: &Path,
    name: &str,
    lpips: Option<Lpips>,
) -> (Sequence, Vec<BinReport>, Vec<SkippedBin>) {
    let sequence = Sequence::open(root, name).unwrap();
    let mut sgm = SgmReconstructor::new(SgmConfig::default());
    let config = EvalConfig {
        bins: model::bins::BinConfig {
            layout: model::bins::BinLayout::Sliding { stride: 3 },
            ..Default::default()
        },
        lpips,
        ..EvalConfig::default()
    };
    let mut calls = 0;
    let (bins, skipped) = evaluate(
        &sequence,
        &mut sgm,
        &mut Raster::Cpu,
        &config,
        &mut |_, _| calls += 1,
    )
    .unwrap();
    assert_eq!(calls, bins.len() + skipped.len(), "progress once per bin");
    (sequence, bins, skipped)
}

fn contains(report: &BinReport, frame: u32) -> bool {
    (report.first..=report.last).contains(&frame)
}

#[test]
fn a_clean_drive_scores_every_bin_with_finite_numbers() {
    let (root, name) = drive("clean");
    let (_, bins, skipped) = run(&root, &name, Some(Lpips::load_default().unwrap()));
    assert!(skipped.is_empty(), "{skipped:?}");
    assert!(bins.len() >= 3, "{} bins", bins.len());
    for bin in &bins {
        assert!(bin.gaussians > 0);
        // Every frame of the bin, left and right.
        assert_eq!(bin.frames.len(), 2 * (bin.last - bin.first + 1) as usize);
        for f in &bin.frames {
            assert!(f.psnr.is_finite() && f.psnr > 8.0, "{f:?}");
            assert!((0.0..=1.0).contains(&f.ssim), "{f:?}");
            assert!(f.lpips.is_some_and(|d| d > 0.0 && d < 1.0), "{f:?}");
            assert!(f.abs_rel.is_some_and(|a| a.is_finite()), "{f:?}");
            assert!(f.lidar_pixels > 50, "{f:?}");
        }
    }
    // The input view re-rendered is perceptually closest; the last frame, 8 m on, farthest.
    let summary = model::eval::Summary::of(&bins);
    let (first, last) = (summary.first.lpips.unwrap(), summary.last.lpips.unwrap());
    assert!(first < last, "first {first} last {last}");
    // Unseen regions: none in the input pair itself; 8 m on, the facades that came into view
    // at the sides are unseen and scored on their own.
    for bin in &bins {
        for f in bin.frames.iter().filter(|f| f.frame == bin.first) {
            assert_eq!((f.unseen_pixels, f.unseen_psnr), (0, None), "{f:?}");
        }
        let last: Vec<_> = bin.frames.iter().filter(|f| f.frame == bin.last).collect();
        let pixels = 136 * 40;
        assert!(
            last.iter()
                .all(|f| f.unseen_pixels > pixels / 50 && f.unseen_pixels < pixels / 2),
            "{last:?}"
        );
    }
    let (unseen, all) = (summary.last.unseen_psnr.unwrap(), summary.last.psnr);
    assert!(
        unseen.is_finite() && unseen > 5.0 && unseen != all,
        "unseen {unseen} dB, all {all} dB"
    );
    // Without the exact depth files (real data) the column is gone, the rest unchanged.
    std::fs::remove_dir_all(root.join("data_2d_exact_depth")).unwrap();
    let (_, bare, _) = run(&root, &name, None);
    assert!(bare
        .iter()
        .flat_map(|b| &b.frames)
        .all(|f| f.unseen_psnr.is_none() && f.unseen_pixels == 0));
    assert_eq!(bare[0].frames[0].psnr, bins[0].frames[0].psnr);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_missing_image_skips_only_the_bins_that_need_it() {
    let (root, name) = drive("missing");
    let gone = layout::image(&root, &name, Side::Right, 12);
    std::fs::remove_file(&gone).unwrap();
    let (_, bins, skipped) = run(&root, &name, None);
    assert!(!skipped.is_empty());
    for s in &skipped {
        assert!(
            s.reason.contains(&gone.display().to_string()),
            "{}",
            s.reason
        );
    }
    assert!(bins.iter().all(|b| !contains(b, 12)));
    assert!(!bins.is_empty(), "bins away from frame 12 are still scored");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_corrupt_png_and_a_size_mismatch_skip_their_bins_with_the_file_named() {
    let (root, name) = drive("corrupt");
    let corrupt = layout::image(&root, &name, Side::Left, 4);
    std::fs::write(&corrupt, b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let small = layout::image(&root, &name, Side::Right, 20);
    image::RgbImage::new(50, 20).save(&small).unwrap();
    let (_, bins, skipped) = run(&root, &name, None);
    let named = |p: &Path| {
        skipped
            .iter()
            .any(|s| s.reason.contains(&p.display().to_string()))
    };
    assert!(named(&corrupt) && named(&small), "{skipped:?}");
    assert!(bins.iter().all(|b| !contains(b, 4) && !contains(b, 20)));
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn an_empty_lidar_scan_leaves_only_that_frames_depth_unscored() {
    let (root, name) = drive("lidar");
    std::fs::write(layout::velodyne(&root, &name, 6), b"").unwrap();
    let (_, bins, skipped) = run(&root, &name, None);
    assert!(skipped.is_empty(), "{skipped:?}");
    let frame6: Vec<_> = bins
        .iter()
        .flat_map(|b| &b.frames)
        .filter(|f| f.frame == 6)
        .collect();
    assert!(!frame6.is_empty());
    for f in frame6 {
        assert_eq!((f.abs_rel, f.lidar_pixels), (None, 0));
        assert_eq!(f.lpips, None, "LPIPS was off");
        assert!(f.psnr.is_finite(), "the image is still scored");
    }
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_non_finite_pose_drops_its_frame_and_is_counted() {
    let (root, name) = drive("pose");
    let path = layout::cam0_to_world(&root, &name);
    let text = std::fs::read_to_string(&path).unwrap();
    let broken: Vec<String> = text
        .lines()
        .map(|l| match l.split_whitespace().next() {
            Some("15") => {
                let mut cells: Vec<&str> = l.split_whitespace().collect();
                cells[4] = "nan";
                cells.join(" ")
            }
            _ => l.to_string(),
        })
        .collect();
    std::fs::write(&path, broken.join("\n") + "\n").unwrap();
    let (sequence, bins, skipped) = run(&root, &name, None);
    assert_eq!(sequence.skipped().len(), 1);
    assert_eq!(sequence.skipped()[0].index, 15);
    assert!(skipped.is_empty());
    assert!(bins.iter().flat_map(|b| &b.frames).all(|f| f.frame != 15));
    let _ = std::fs::remove_dir_all(&root);
}
