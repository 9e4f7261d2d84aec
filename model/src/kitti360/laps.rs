//! A drive played several times end to end, each lap continuing where the last one left
//! off: a drive longer than any sequence at hand (an hour of driving from eight minutes of
//! generated frames) for the benchmarks that measure what grows with the length of a drive.
//! The images repeat; the poses and timestamps go on, so the map keeps meeting new ground.

use glam::DAffine3;

use super::poses::FramePose;

/// Frame spacing assumed where the frames carry no timestamps: KITTI-360's 10 Hz.
const FRAME_NS: i64 = 100_000_000;

/// `frames` played `laps` times in a row. Lap `k`'s poses are `D^k * P_i`, where the rigid
/// motion `D` puts the first frame one step past the last (the step being the drive's last
/// frame-to-frame motion), so each lap picks up where the one before ended, heading the same
/// way; its timestamps are shifted by the lap's duration plus that step. Frame indices
/// repeat (each lap shows the same images). With fewer than two frames or `laps <= 1`, the
/// frames as they are (an empty list for `laps == 0`).
pub fn chain_laps(frames: &[FramePose], laps: u32) -> Vec<FramePose> {
    let (Some(first), [.., prev, last]) = (frames.first(), frames) else {
        return match laps {
            0 => Vec::new(),
            _ => frames.to_vec(),
        };
    };
    let step = prev.left_to_world.inverse() * last.left_to_world;
    let lap_motion = last.left_to_world * step * first.left_to_world.inverse();
    let lap_ns = match (first.timestamp_ns, prev.timestamp_ns, last.timestamp_ns) {
        (Some(t0), Some(tp), Some(tl)) => (tl - t0) + (tl - tp),
        _ => frames.len() as i64 * FRAME_NS,
    };
    let mut out = Vec::with_capacity(frames.len() * laps as usize);
    let mut motion = DAffine3::IDENTITY;
    for lap in 0..i64::from(laps) {
        out.extend(frames.iter().map(|f| {
            FramePose {
                index: f.index,
                left_to_world: motion * f.left_to_world,
                timestamp_ns: f
                    .timestamp_ns
                    .map(|t| t.saturating_add(lap.saturating_mul(lap_ns))),
            }
        }));
        motion = lap_motion * motion;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// A drive turning at a constant rate: frame `i` at angle `i * yaw` on a circle.
    fn arc(n: u32, yaw: f64, radius: f64) -> Vec<FramePose> {
        (0..n)
            .map(|i| {
                let a = f64::from(i) * yaw;
                FramePose {
                    index: i,
                    left_to_world: DAffine3::from_rotation_translation(
                        glam::DQuat::from_rotation_z(a),
                        DVec3::new(radius * a.sin(), radius * (1.0 - a.cos()), 1.5),
                    ),
                    timestamp_ns: Some(1_000 + i64::from(i) * FRAME_NS),
                }
            })
            .collect()
    }

    #[test]
    fn three_laps_of_an_arc_continue_the_arc_frame_by_frame() {
        let one = arc(40, 0.01, 50.0);
        let chained = chain_laps(&one, 3);
        let whole = arc(120, 0.01, 50.0);
        assert_eq!(chained.len(), 120);
        for (got, want) in chained.iter().zip(&whole) {
            assert!(got.left_to_world.abs_diff_eq(want.left_to_world, 1e-9));
            assert_eq!(got.timestamp_ns, want.timestamp_ns);
            assert_eq!(got.index, want.index % 40);
        }
    }

    #[test]
    fn frames_without_timestamps_keep_none_and_short_drives_are_returned_as_they_are() {
        let mut one = arc(10, 0.0, 1.0);
        one.iter_mut().for_each(|f| f.timestamp_ns = None);
        let chained = chain_laps(&one, 2);
        assert!(chained.iter().all(|f| f.timestamp_ns.is_none()));
        // A rig standing still: every lap stays where it stands.
        assert!(chained
            .iter()
            .all(|f| f.left_to_world == one[0].left_to_world));
        let single = arc(1, 0.1, 1.0);
        assert_eq!(chain_laps(&single, 5), single);
        assert!(chain_laps(&one, 0).is_empty());
        assert_eq!(chain_laps(&one, 1), one);
    }

    #[test]
    fn a_thousand_laps_stay_rigid_and_finite() {
        let chained = chain_laps(&arc(3, 0.3, 1e4), 1000);
        let last = chained.last().expect("frames").left_to_world;
        let r = last.matrix3;
        let err = (r.transpose() * r - glam::DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(err < 1e-9, "orthonormality error {err}");
        assert!(last.translation.is_finite());
        assert_eq!(
            chained.last().and_then(|f| f.timestamp_ns),
            Some(1_000 + 2_999 * FRAME_NS)
        );
    }
}
