//! Scores of an evaluation and the paper's table made from them (first / centre / last
//! frame and bin average, PSNR, SSIM, LPIPS when scored, AbsRel, SqRel), as markdown and
//! JSON.

use serde::Serialize;

use crate::bins::Role;
use crate::frame::Side;

/// The scores of one rendered frame against its recording.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameScore {
    /// The frame number in the sequence.
    pub frame: u32,
    /// Which camera.
    #[serde(serialize_with = "side_name")]
    pub side: Side,
    /// First, centre or last frame of the bin, or none of them.
    pub role: Option<Role>,
    /// PSNR in dB against the recorded image.
    pub psnr: f64,
    /// SSIM against the recorded image (scikit-image's settings).
    pub ssim: f64,
    /// LPIPS (AlexNet) against the recorded image, lower is better; `None` when the
    /// evaluation ran without LPIPS.
    pub lpips: Option<f64>,
    /// Mean |d - d_lidar| / d_lidar over valid LiDAR pixels; `None` without LiDAR there.
    pub abs_rel: Option<f64>,
    /// Mean (d - d_lidar)^2 / d_lidar over valid LiDAR pixels; `None` without LiDAR there.
    pub sq_rel: Option<f64>,
    /// LiDAR pixels the depth scores average over.
    pub lidar_pixels: usize,
    /// PSNR on the pixels whose true surface no input view saw (see `unseen`); `None` on
    /// real data (no exact depth) or with too few such pixels.
    pub unseen_psnr: Option<f64>,
    /// How many pixels were unseen (0 without exact depth).
    pub unseen_pixels: usize,
}

fn side_name<S: serde::Serializer>(side: &Side, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(match side {
        Side::Left => "left",
        Side::Right => "right",
    })
}

/// Everything measured on one bin.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BinReport {
    /// The sequence the bin belongs to.
    pub sequence: String,
    /// Frame numbers of the bin's first, centre and last frames.
    pub first: u32,
    /// See `first`.
    pub centre: u32,
    /// See `first`.
    pub last: u32,
    /// Gaussians the reconstructor returned.
    pub gaussians: usize,
    /// Wall time of the reconstruction, milliseconds.
    pub reconstruct_ms: f64,
    /// The depth range (near, far, metres) the candidates spanned when the reconstructor
    /// fitted it to the bin (`auto_depth_range`); null when it kept its preset's.
    pub fitted_depth_range_m: Option<[f32; 2]>,
    /// Every frame of the bin, left and right.
    pub frames: Vec<FrameScore>,
}

/// A bin that could not be evaluated, and why (a frame that failed to load, a
/// reconstructor error): counted, not fatal.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SkippedBin {
    /// The sequence.
    pub sequence: String,
    /// The bin's first frame number.
    pub first: u32,
    /// The error, as text.
    pub reason: String,
}

/// Means of the metrics over a set of frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct MeanScores {
    /// Mean PSNR, dB.
    pub psnr: f64,
    /// Mean SSIM.
    pub ssim: f64,
    /// Mean LPIPS over the frames that were scored with it (`None` if none were).
    pub lpips: Option<f64>,
    /// Mean AbsRel over the frames that had LiDAR (`None` if none had).
    pub abs_rel: Option<f64>,
    /// Mean SqRel over the frames that had LiDAR.
    pub sq_rel: Option<f64>,
    /// Mean unseen-region PSNR over the frames that had one (`None` if none had).
    pub unseen_psnr: Option<f64>,
    /// How many values the image means average.
    pub count: usize,
}

impl MeanScores {
    /// The means over `scores` (each bin weighs by its own frames; callers average bins).
    pub fn of<'a>(scores: impl IntoIterator<Item = &'a MeanScores>) -> Self {
        let scores: Vec<_> = scores.into_iter().collect();
        let mean = |v: Vec<f64>| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
        Self {
            psnr: mean(scores.iter().map(|s| s.psnr).collect()).unwrap_or(f64::NAN),
            ssim: mean(scores.iter().map(|s| s.ssim).collect()).unwrap_or(f64::NAN),
            lpips: mean(scores.iter().filter_map(|s| s.lpips).collect()),
            abs_rel: mean(scores.iter().filter_map(|s| s.abs_rel).collect()),
            sq_rel: mean(scores.iter().filter_map(|s| s.sq_rel).collect()),
            unseen_psnr: mean(scores.iter().filter_map(|s| s.unseen_psnr).collect()),
            count: scores.len(),
        }
    }

    fn of_frames<'a>(frames: impl IntoIterator<Item = &'a FrameScore>) -> Self {
        let per_frame: Vec<MeanScores> = frames.into_iter().map(MeanScores::from).collect();
        Self::of(&per_frame)
    }
}

impl From<&FrameScore> for MeanScores {
    /// One frame's scores as a mean of one.
    fn from(f: &FrameScore) -> Self {
        Self {
            psnr: f.psnr,
            ssim: f.ssim,
            lpips: f.lpips,
            abs_rel: f.abs_rel,
            sq_rel: f.sq_rel,
            unseen_psnr: f.unseen_psnr,
            count: 1,
        }
    }
}

/// The paper's table: each row averages per bin first (left and right together), then over
/// bins, so long and short bins weigh the same.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// The input frame re-rendered.
    pub first: MeanScores,
    /// The centre frame.
    pub centre: MeanScores,
    /// The last frame.
    pub last: MeanScores,
    /// Every frame of the bin.
    pub average: MeanScores,
}

impl Summary {
    /// The table over `bins`.
    pub fn of(bins: &[BinReport]) -> Self {
        let row = |role: Option<Role>| {
            let per_bin: Vec<MeanScores> = bins
                .iter()
                .map(|b| {
                    MeanScores::of_frames(
                        b.frames.iter().filter(|f| role.is_none() || f.role == role),
                    )
                })
                .collect();
            MeanScores::of(&per_bin)
        };
        Self {
            first: row(Some(Role::First)),
            centre: row(Some(Role::Centre)),
            last: row(Some(Role::Last)),
            average: row(None),
        }
    }
}

/// The whole evaluation of one method on one data root.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EvalReport {
    /// The reconstructor's name.
    pub method: String,
    /// The rasterizer that drew the renders.
    pub raster: String,
    /// Bin length in metres.
    pub bin_length_m: f64,
    /// The depth range LiDAR pixels must fall in to count, metres.
    pub depth_range_m: (f32, f32),
    /// The table.
    pub summary: Summary,
    /// Mean Gaussians per bin.
    pub mean_gaussians: f64,
    /// Mean reconstruction time per bin, milliseconds.
    pub mean_reconstruct_ms: f64,
    /// Bins whose depth candidates were fitted to the scene (`auto_depth_range`).
    pub fitted_range_bins: usize,
    /// Bins that could not be evaluated.
    pub skipped: Vec<SkippedBin>,
    /// Every evaluated bin.
    pub bins: Vec<BinReport>,
}

impl EvalReport {
    /// The report of `bins` (summary and means computed here).
    pub fn new(
        method: String,
        raster: String,
        bin_length_m: f64,
        depth_range_m: (f32, f32),
        bins: Vec<BinReport>,
        skipped: Vec<SkippedBin>,
    ) -> Self {
        let n = bins.len().max(1) as f64;
        Self {
            summary: Summary::of(&bins),
            mean_gaussians: bins.iter().map(|b| b.gaussians as f64).sum::<f64>() / n,
            mean_reconstruct_ms: bins.iter().map(|b| b.reconstruct_ms).sum::<f64>() / n,
            fitted_range_bins: bins
                .iter()
                .filter(|b| b.fitted_depth_range_m.is_some())
                .count(),
            method,
            raster,
            bin_length_m,
            depth_range_m,
            skipped,
            bins,
        }
    }

    /// The table in markdown: one row per method line, columns as the paper's tables.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "# Evaluation: {}\n\n{} bins ({} skipped), bins of {} m, renders on {}, \
             LiDAR depth in [{}, {}] m; mean {:.0} Gaussians and {:.1} ms per reconstruction.\n\n",
            self.method,
            self.bins.len(),
            self.skipped.len(),
            self.bin_length_m,
            self.raster,
            self.depth_range_m.0,
            self.depth_range_m.1,
            self.mean_gaussians,
            self.mean_reconstruct_ms,
        );
        if self.fitted_range_bins > 0 {
            s.push_str(&format!(
                "Depth candidates fitted to the scene in {} of the bins.\n\n",
                self.fitted_range_bins
            ));
        }
        s.push_str(&table_header(self.has_lpips(), self.has_unseen()));
        s.push_str(&self.table_row());
        if !self.skipped.is_empty() {
            s.push_str("\nSkipped bins:\n\n");
            for b in &self.skipped {
                s.push_str(&format!(
                    "- {} frame {}: {}\n",
                    b.sequence, b.first, b.reason
                ));
            }
        }
        s
    }

    /// Whether any frame was scored with LPIPS, i.e. whether the table has LPIPS columns.
    pub fn has_lpips(&self) -> bool {
        self.summary.average.lpips.is_some()
    }

    /// Whether any frame had an unseen-region PSNR (generated drives), i.e. whether the
    /// table has its two columns.
    pub fn has_unseen(&self) -> bool {
        self.summary.average.unseen_psnr.is_some()
    }

    /// This method's line of the table (see [`table_header`], called with
    /// [`EvalReport::has_lpips`] and [`EvalReport::has_unseen`]).
    pub fn table_row(&self) -> String {
        let t = &self.summary;
        let with_lpips = self.has_lpips();
        let unseen = self.has_unseen().then(|| {
            [t.last, t.average].map(|m| m.unseen_psnr.map_or("n/a".into(), |v| format!("{v:.2}")))
        });
        let cells: Vec<String> = [t.first, t.centre, t.last, t.average]
            .iter()
            .flat_map(|m| {
                let lpips = with_lpips.then(|| opt(m.lpips));
                [format!("{:.2}", m.psnr), format!("{:.3}", m.ssim)]
                    .into_iter()
                    .chain(lpips)
                    .chain([opt(m.abs_rel), opt(m.sq_rel)])
            })
            .chain(unseen.into_iter().flatten())
            .collect();
        format!("| {} | {} |\n", self.method, cells.join(" | "))
    }
}

fn opt(v: Option<f64>) -> String {
    v.map_or("n/a".into(), |v| format!("{v:.3}"))
}

/// The header of the paper-style table: for each of first, centre, last frame and the bin
/// average, PSNR, SSIM, LPIPS (only `with_lpips`, so runs without it keep the narrower
/// table), AbsRel and SqRel; then, `with_unseen`, the unseen-region PSNR of the last frame
/// and of the bin average. Rows of one table must agree on both.
pub fn table_header(with_lpips: bool, with_unseen: bool) -> String {
    let groups = ["first", "centre", "last", "bin avg"];
    let metrics: Vec<&str> = ["PSNR", "SSIM", "LPIPS", "AbsRel", "SqRel"]
        .into_iter()
        .filter(|&m| with_lpips || m != "LPIPS")
        .collect();
    let unseen = ["last unseen PSNR", "bin avg unseen PSNR"]
        .into_iter()
        .filter(|_| with_unseen)
        .map(String::from);
    let names: Vec<String> = groups
        .iter()
        .flat_map(|g| metrics.iter().map(move |m| format!("{g} {m}")))
        .chain(unseen)
        .collect();
    format!(
        "| method | {} |\n|---|{}\n",
        names.join(" | "),
        "---:|".repeat(names.len())
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn score(frame: u32, role: Option<Role>, psnr: f64, abs_rel: Option<f64>) -> FrameScore {
        FrameScore {
            frame,
            side: Side::Left,
            role,
            psnr,
            ssim: psnr / 100.0,
            lpips: None,
            unseen_psnr: None,
            unseen_pixels: 0,
            abs_rel,
            sq_rel: abs_rel.map(|a| a * 2.0),
            lidar_pixels: 10,
        }
    }

    fn bin(frames: Vec<FrameScore>) -> BinReport {
        BinReport {
            sequence: "s".into(),
            first: 0,
            centre: 1,
            last: 2,
            gaussians: 100,
            reconstruct_ms: 5.0,
            fitted_depth_range_m: None,
            frames,
        }
    }

    #[test]
    fn rows_average_within_bins_then_over_bins() {
        let a = bin(vec![
            score(0, Some(Role::First), 30.0, Some(0.1)),
            score(1, Some(Role::Centre), 20.0, None),
            score(2, None, 20.0, Some(0.3)),
            score(3, Some(Role::Last), 10.0, Some(0.2)),
        ]);
        let b = bin(vec![
            score(5, Some(Role::First), 40.0, Some(0.3)),
            score(6, Some(Role::Centre), 30.0, Some(0.1)),
            score(7, Some(Role::Last), 20.0, Some(0.1)),
        ]);
        let t = Summary::of(&[a, b]);
        assert_eq!(t.first.psnr, 35.0);
        assert!((t.first.abs_rel.unwrap() - 0.2).abs() < 1e-12);
        // Centre: bin a has no LiDAR there, so AbsRel comes from bin b alone.
        assert!((t.centre.abs_rel.unwrap() - 0.1).abs() < 1e-12);
        // Bin a averages 20 dB over its 4 frames, bin b 30 dB over 3: the average is 25.
        assert_eq!(t.average.psnr, 25.0);
        assert_eq!(t.average.count, 2);
    }

    fn report(bins: Vec<BinReport>) -> EvalReport {
        EvalReport::new("sgm".into(), "cpu".into(), 8.0, (1e-3, 80.0), bins, vec![])
    }

    /// The markdown's header and `sgm` row, each split into its cells.
    fn table(report: &EvalReport) -> (Vec<String>, Vec<String>) {
        let md = report.markdown();
        let cells = |prefix: &str| -> Vec<String> {
            let line = md.lines().find(|l| l.starts_with(prefix)).unwrap();
            line.trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect()
        };
        (cells("| method"), cells("| sgm"))
    }

    #[test]
    fn bins_with_a_fitted_depth_range_are_counted_and_said() {
        let frames = || vec![score(0, Some(Role::Centre), 20.0, Some(0.1))];
        let plain = report(vec![bin(frames()), bin(frames())]);
        assert_eq!(plain.fitted_range_bins, 0);
        assert!(!plain.markdown().contains("fitted"));
        let fitted = BinReport {
            fitted_depth_range_m: Some([2.0, 10.0]),
            ..bin(frames())
        };
        let mixed = report(vec![bin(frames()), fitted]);
        assert_eq!(mixed.fitted_range_bins, 1);
        assert!(mixed
            .markdown()
            .contains("fitted to the scene in 1 of the bins"));
        let json = serde_json::to_value(&mixed).unwrap();
        assert_eq!(json["bins"][1]["fitted_depth_range_m"][1], 10.0);
        assert!(json["bins"][0]["fitted_depth_range_m"].is_null());
    }

    #[test]
    fn markdown_has_one_cell_per_metric_and_group() {
        let report = report(vec![bin(vec![score(0, Some(Role::First), 30.0, None)])]);
        let (header, row) = table(&report);
        assert_eq!(row.len(), 17);
        assert_eq!(header.len(), row.len());
        assert!(!report.has_lpips());
        assert!(header.iter().all(|h| !h.contains("LPIPS")), "{header:?}");
        assert!(row.contains(&"30.00".to_string()) && row.contains(&"n/a".to_string()));
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["bins"][0]["frames"][0]["side"], "left");
        assert_eq!(
            json["bins"][0]["frames"][0]["lpips"],
            serde_json::Value::Null
        );
        assert_eq!(json["summary"]["first"]["psnr"], 30.0);
    }

    #[test]
    fn lpips_is_averaged_per_bin_then_over_bins_and_gets_a_column_per_group() {
        let lpips = |mut s: FrameScore, v: f64| {
            s.lpips = Some(v);
            s
        };
        let a = bin(vec![
            lpips(score(0, Some(Role::First), 30.0, None), 0.1),
            lpips(score(1, Some(Role::Last), 20.0, None), 0.3),
        ]);
        let b = bin(vec![
            lpips(score(5, Some(Role::First), 30.0, None), 0.3),
            lpips(score(6, None, 20.0, None), 0.4),
            lpips(score(7, Some(Role::Last), 20.0, None), 0.5),
        ]);
        let report = report(vec![a, b]);
        let t = report.summary;
        assert!((t.first.lpips.unwrap() - 0.2).abs() < 1e-12);
        assert!((t.last.lpips.unwrap() - 0.4).abs() < 1e-12);
        // Bin a averages 0.2, bin b 0.4: the bin average is 0.3, not the frame mean 0.32.
        assert!((t.average.lpips.unwrap() - 0.3).abs() < 1e-12);
        assert_eq!(t.centre.lpips, None, "no centre frame scored");

        let (header, row) = table(&report);
        assert_eq!(row.len(), 21);
        assert_eq!(header.len(), row.len());
        let at = |name: &str| header.iter().position(|h| h == name).unwrap();
        assert_eq!(at("first LPIPS"), at("first SSIM") + 1);
        assert_eq!(row[at("first LPIPS")], "0.200");
        assert_eq!(row[at("centre LPIPS")], "n/a");
        assert_eq!(row[at("bin avg LPIPS")], "0.300");
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["bins"][1]["frames"][2]["lpips"], 0.5);
        assert!((json["summary"]["average"]["lpips"].as_f64().unwrap() - 0.3).abs() < 1e-12);
    }
}
