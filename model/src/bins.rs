//! Bins along a trajectory (paper section 4.1, after OmniScene's protocol): a bin is a run
//! of consecutive frames whose first and last camera centres are a set distance apart
//! (8.0 m by default). The first stereo pair is the input; the centre and last frames are
//! novel targets; every frame of the bin counts in the bin average.

use glam::DAffine3;

/// How bins are cut from a trajectory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BinConfig {
    /// Straight-line distance between the first and last camera centres of a bin, metres.
    /// A bin closes at the first frame at least this far from its first frame.
    pub length_m: f64,
    /// Where bins start.
    pub layout: BinLayout,
}

/// Where consecutive bins start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinLayout {
    /// A bin may start at every `stride`-th frame, so bins overlap (the paper's protocol
    /// counts a bin per start frame: stride 1).
    Sliding {
        /// Frames between the first frames of consecutive bins (at least 1).
        stride: usize,
    },
    /// Each bin starts at the previous bin's last frame, as the streaming node cuts a drive.
    Consecutive,
}

impl Default for BinConfig {
    fn default() -> Self {
        Self {
            length_m: 8.0,
            layout: BinLayout::Sliding { stride: 1 },
        }
    }
}

/// One bin: positions into the trajectory slice it was cut from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bin {
    /// The input frame (its left camera defines the bin frame).
    pub first: usize,
    /// The frame whose distance from the first is nearest half the bin length (the lower
    /// one on a tie): the middle of the stretch even when the speed changes within it.
    pub centre: usize,
    /// The first frame at least the bin length away from the first.
    pub last: usize,
}

impl Bin {
    /// Every frame of the bin, first to last.
    pub fn frames(&self) -> std::ops::RangeInclusive<usize> {
        self.first..=self.last
    }

    /// The role of frame `i` in this bin, if it is one of the three named frames.
    pub fn role(&self, i: usize) -> Option<Role> {
        if i == self.first {
            Some(Role::First)
        } else if i == self.centre {
            Some(Role::Centre)
        } else if i == self.last {
            Some(Role::Last)
        } else {
            None
        }
    }
}

/// The named frames of a bin, the columns of the paper's tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// The input frame.
    First,
    /// The frame half way along.
    Centre,
    /// The frame the bin length away.
    Last,
}

/// Cuts `left_to_world` (the trajectory, one pose per frame, in order) into bins. A start
/// frame whose bin would run past the end of the trajectory gives no bin; a bin whose
/// frames hold a non-finite position is skipped.
pub fn make_bins(left_to_world: &[DAffine3], config: &BinConfig) -> Vec<Bin> {
    let centres: Vec<_> = left_to_world.iter().map(|p| p.translation).collect();
    let mut bins = Vec::new();
    let mut start = 0;
    while start < centres.len() {
        let origin = centres[start];
        let last = (start + 1..centres.len()).find(|&j| {
            let d = centres[j].distance(origin);
            !d.is_finite() || d >= config.length_m
        });
        let Some(last) = last else { break };
        let finite = centres[start..=last].iter().all(|c| c.is_finite());
        if finite {
            let half = 0.5 * config.length_m;
            let centre = (start..=last)
                .min_by(|&a, &b| {
                    let da = (centres[a].distance(origin) - half).abs();
                    let db = (centres[b].distance(origin) - half).abs();
                    da.total_cmp(&db)
                })
                .unwrap_or(start);
            bins.push(Bin {
                first: start,
                centre,
                last,
            });
        }
        start = match config.layout {
            BinLayout::Sliding { stride } => start + stride.max(1),
            BinLayout::Consecutive if finite => last,
            BinLayout::Consecutive => last + 1,
        };
    }
    bins
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn straight(steps: &[f64]) -> Vec<DAffine3> {
        let mut x = 1.0e5;
        let mut out = vec![DAffine3::from_translation(DVec3::new(x, 2.0e5, 30.0))];
        for s in steps {
            x += s;
            out.push(DAffine3::from_translation(DVec3::new(x, 2.0e5, 30.0)));
        }
        out
    }

    #[test]
    fn bins_close_at_the_first_frame_eight_metres_away() {
        // 1 m per frame: frame 8 is exactly 8 m from frame 0.
        let poses = straight(&[1.0; 20]);
        let bins = make_bins(&poses, &BinConfig::default());
        assert_eq!(bins.len(), 13); // starts 0..=12 reach a frame 8 m on
        assert_eq!(
            bins[0],
            Bin {
                first: 0,
                centre: 4,
                last: 8
            }
        );
        assert_eq!(bins[12].last, 20);
    }

    #[test]
    fn centre_follows_distance_not_index_when_speed_changes() {
        // Slow at first (0.5 m per frame), then fast (2 m per frame).
        let poses = straight(&[0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 2.0, 2.0]);
        let bins = make_bins(&poses, &BinConfig::default());
        // Distances from frame 0: 0, .5, 1, ..., 4 (frame 8), 6, 8 (frame 10).
        assert_eq!(
            bins[0],
            Bin {
                first: 0,
                centre: 8,
                last: 10
            }
        );
    }

    #[test]
    fn consecutive_bins_share_their_boundary_frame() {
        let poses = straight(&[2.0; 12]);
        let config = BinConfig {
            layout: BinLayout::Consecutive,
            ..BinConfig::default()
        };
        let bins = make_bins(&poses, &config);
        let spans: Vec<_> = bins.iter().map(|b| (b.first, b.last)).collect();
        assert_eq!(spans, vec![(0, 4), (4, 8), (8, 12)]);
    }

    #[test]
    fn short_and_standing_trajectories_give_no_bins() {
        assert!(make_bins(&[], &BinConfig::default()).is_empty());
        assert!(make_bins(&straight(&[0.0; 30]), &BinConfig::default()).is_empty());
        assert!(make_bins(&straight(&[1.0; 7]), &BinConfig::default()).is_empty());
    }

    #[test]
    fn non_finite_positions_never_enter_a_bin() {
        let mut poses = straight(&[1.0; 20]);
        poses[3].translation.x = f64::NAN;
        let bins = make_bins(&poses, &BinConfig::default());
        assert!(bins.iter().all(|b| !b.frames().contains(&3)));
        assert!(!bins.is_empty());
    }
}
