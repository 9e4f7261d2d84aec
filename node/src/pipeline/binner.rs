//! Cuts the synchronised frame stream into bins as the evaluation protocol does
//! ([`model::bins`], consecutive layout): a bin opens at a frame and closes at the first later
//! frame at least the bin length (8.0 m) from it; that frame opens the next bin. The opening
//! frame is announced at once, so its stereo pair reaches the worker before the bin closes
//! (causal); the later frames are kept only as far as `keep` says.

use glam::{DAffine3, DVec3};

/// Settings of the binner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BinnerConfig {
    /// Distance between a bin's first and last camera centres, metres.
    pub length_m: f64,
    /// Which later frames of a bin are kept (for evaluation or renders).
    pub keep: Keep,
    /// The id of the first bin opened: 0 for a new map, the next after the last published
    /// bin for a node that resumed a saved map (ids are never reused).
    pub first_bin_id: u64,
}

/// Which frames after the first a bin keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Keep {
    /// Only the first frame (all the reconstructor needs).
    FirstOnly,
    /// Every frame of the bin (evaluation while streaming).
    All,
}

impl Default for BinnerConfig {
    fn default() -> Self {
        Self {
            length_m: 8.0,
            keep: Keep::FirstOnly,
            first_bin_id: 0,
        }
    }
}

/// What a frame did to the bins.
#[derive(Debug, PartialEq)]
pub enum BinEvent<F> {
    /// The frame opened bin `bin_id`: send it to the worker now.
    Opened {
        /// Consecutive from `BinnerConfig::first_bin_id` (0 by default).
        bin_id: u64,
        /// The bin's first frame (its left camera defines the bin frame).
        first: F,
    },
    /// The frame lies inside the open bin.
    Inside,
    /// The frame closed bin `bin_id` and opened bin `bin_id + 1` with itself as first frame.
    Closed {
        /// The bin that closed.
        bin_id: u64,
        /// The frames it kept after its first, the closing frame last (see [`Keep`]).
        kept: Vec<F>,
        /// The next bin's first frame (the closing frame).
        next_first: F,
    },
    /// The frame's pose is not finite: it is dropped (and should be counted).
    Rejected,
}

/// The streaming binner.
#[derive(Debug)]
pub struct Binner<F> {
    config: BinnerConfig,
    open: Option<OpenBin<F>>,
    next_id: u64,
}

#[derive(Debug)]
struct OpenBin<F> {
    id: u64,
    origin: DVec3,
    kept: Vec<F>,
}

impl<F: Clone> Binner<F> {
    /// A binner with no open bin.
    pub fn new(config: BinnerConfig) -> Self {
        Self {
            config,
            open: None,
            next_id: config.first_bin_id,
        }
    }

    /// The open bin's id, if any.
    pub fn open_bin(&self) -> Option<u64> {
        self.open.as_ref().map(|b| b.id)
    }

    /// Ends the open bin without a closing frame, because the input started over (the
    /// synchroniser confirmed a jump in time: a replay, a clock reset); its id, if one was
    /// open. The next frame opens a new bin; ids go on, so no id is used twice.
    pub fn reset(&mut self) -> Option<u64> {
        self.open.take().map(|b| b.id)
    }

    /// Whether the next frame, at `left_to_world`, opens a bin (the first frame, or one that
    /// closes the open bin), so a caller can prepare what only an opening frame needs; a
    /// pose that is not finite opens none.
    pub fn opens(&self, left_to_world: &DAffine3) -> bool {
        let position = left_to_world.translation;
        if !(position.is_finite() && left_to_world.matrix3.is_finite()) {
            return false;
        }
        self.open
            .as_ref()
            .is_none_or(|open| position.distance(open.origin) >= self.config.length_m)
    }

    /// Adds the next frame with its left camera pose.
    pub fn push(&mut self, frame: F, left_to_world: DAffine3) -> BinEvent<F> {
        let position = left_to_world.translation;
        if !(position.is_finite() && left_to_world.matrix3.is_finite()) {
            return BinEvent::Rejected;
        }
        let Some(open) = &mut self.open else {
            let bin_id = self.open_new(position);
            return BinEvent::Opened {
                bin_id,
                first: frame,
            };
        };
        let closes = position.distance(open.origin) >= self.config.length_m;
        if !closes {
            if self.config.keep == Keep::All {
                open.kept.push(frame);
            }
            return BinEvent::Inside;
        }
        let bin_id = open.id;
        let mut kept = std::mem::take(&mut open.kept);
        if self.config.keep == Keep::All {
            kept.push(frame.clone());
        }
        self.open_new(position);
        BinEvent::Closed {
            bin_id,
            kept,
            next_first: frame,
        }
    }

    fn open_new(&mut self, origin: DVec3) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        self.open = Some(OpenBin {
            id,
            origin,
            kept: Vec::new(),
        });
        id
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::bins::{make_bins, BinConfig, BinLayout};

    fn trajectory() -> Vec<DAffine3> {
        // Speeds changing between 0.3 and 1.4 m per frame along a gentle curve, far out.
        let mut p = DVec3::new(1.0e5, -3.0e5, 12.0);
        let mut heading: f64 = 0.3;
        (0..200)
            .map(|k| {
                let step = 0.85 + 0.55 * (k as f64 * 0.07).sin();
                heading += 0.01 * (k as f64 * 0.03).cos();
                p += DVec3::new(heading.cos(), heading.sin(), 0.0) * step;
                DAffine3::from_translation(p)
            })
            .collect()
    }

    #[test]
    fn streaming_bins_equal_the_evaluation_protocols_consecutive_bins() {
        let poses = trajectory();
        let config = BinConfig {
            length_m: 8.0,
            layout: BinLayout::Consecutive,
        };
        let expected: Vec<(usize, usize)> = make_bins(&poses, &config)
            .iter()
            .map(|b| (b.first, b.last))
            .collect();
        let mut binner = Binner::new(BinnerConfig {
            keep: Keep::All,
            ..BinnerConfig::default()
        });
        let mut firsts = Vec::new();
        let mut got = Vec::new();
        for (i, pose) in poses.iter().enumerate() {
            let opens = binner.opens(pose);
            let event = binner.push(i, *pose);
            assert_eq!(opens, !matches!(event, BinEvent::Inside), "frame {i}");
            match event {
                BinEvent::Opened { bin_id, first } => firsts.push((bin_id, first)),
                BinEvent::Closed {
                    bin_id,
                    kept,
                    next_first,
                } => {
                    let first = firsts.last().unwrap();
                    assert_eq!(first.0, bin_id);
                    assert_eq!(*kept.last().unwrap(), i);
                    assert_eq!(kept.len(), i - first.1);
                    got.push((first.1, i));
                    firsts.push((bin_id + 1, next_first));
                }
                BinEvent::Inside => {}
                BinEvent::Rejected => panic!("finite trajectory"),
            }
        }
        assert!(expected.len() > 10);
        assert_eq!(got, expected);
    }

    #[test]
    fn a_reset_ends_the_open_bin_and_the_next_frame_opens_the_next_id() {
        let mut binner = Binner::new(BinnerConfig::default());
        let at = |x: f64| DAffine3::from_translation(DVec3::new(x, 0.0, 0.0));
        assert_eq!(binner.reset(), None, "nothing open yet");
        let nan = DAffine3::from_translation(DVec3::new(f64::NAN, 0.0, 0.0));
        assert!(
            !binner.opens(&nan),
            "a pose that is not finite opens nothing"
        );
        assert!(binner.opens(&at(100.0)), "the first frame opens a bin");
        binner.push(0, at(100.0));
        assert_eq!(binner.push(1, at(104.0)), BinEvent::Inside);
        assert_eq!(binner.reset(), Some(0));
        assert_eq!(binner.open_bin(), None);
        // A replay from the start, 4 m behind the old bin's origin: a bin of its own.
        assert!(matches!(
            binner.push(2, at(96.0)),
            BinEvent::Opened {
                bin_id: 1,
                first: 2
            }
        ));
        assert_eq!(binner.push(3, at(100.0)), BinEvent::Inside);
        assert!(matches!(
            binner.push(4, at(104.0)),
            BinEvent::Closed {
                bin_id: 1,
                next_first: 4,
                ..
            }
        ));
    }

    #[test]
    fn non_finite_poses_are_rejected_and_do_not_disturb_the_bin() {
        let mut binner = Binner::new(BinnerConfig::default());
        let at = |x: f64| DAffine3::from_translation(DVec3::new(x, 0.0, 0.0));
        assert!(matches!(
            binner.push(0, at(0.0)),
            BinEvent::Opened { bin_id: 0, .. }
        ));
        let mut bad = at(3.0);
        bad.translation.y = f64::NAN;
        assert_eq!(binner.push(1, bad), BinEvent::Rejected);
        assert_eq!(binner.push(2, at(7.9)), BinEvent::Inside);
        assert!(matches!(
            binner.push(3, at(8.0)),
            BinEvent::Closed {
                bin_id: 0,
                next_first: 3,
                ..
            }
        ));
        assert_eq!(binner.open_bin(), Some(1));
    }

    #[test]
    fn a_resumed_binner_starts_at_its_first_bin_id() {
        let mut binner = Binner::new(BinnerConfig {
            first_bin_id: 7,
            ..BinnerConfig::default()
        });
        let at = |x: f64| DAffine3::from_translation(DVec3::new(x, 0.0, 0.0));
        assert!(matches!(
            binner.push(0, at(0.0)),
            BinEvent::Opened { bin_id: 7, .. }
        ));
        assert!(matches!(
            binner.push(1, at(8.0)),
            BinEvent::Closed { bin_id: 7, .. }
        ));
        assert_eq!(binner.open_bin(), Some(8));
    }
}
