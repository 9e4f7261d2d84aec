//! Where the progressive pass puts its pseudo stereo pairs: one pair per entry of the
//! `pseudo_poses` setting, at the bin's own later poses when they are known (`eval` knows
//! the whole bin's trajectory: evenly spaced, ending at the last, so `[4, 8]` gives the
//! centre and the last), otherwise at those distances ahead of the last input camera along
//! the trajectory (the node opens a bin at its first frame and knows nothing later). The
//! pseudo right camera sits where the rig puts it: the real pair's left-to-right offset,
//! carried in the pseudo left camera's frame.

use glam::Vec3;
use renderer::Camera;

/// A pseudo stereo pair: left and right cameras, bin-local.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PseudoPair {
    /// The left camera.
    pub left: Camera,
    /// The right camera (the rig's offset from `left`).
    pub right: Camera,
}

/// The pseudo pairs for a bin whose real input pairs are `real` (left, right; the first is
/// the bin frame), one per finite entry of `distances`: at evenly spaced cameras of `ahead`
/// (bin-local left cameras of the bin's later frames; the k-th of n at index
/// ceil(k m / n) - 1 of m, duplicates once) when given, else at each distance in metres
/// ahead. "Ahead" is the direction from the first to the last real left camera when they
/// are more than 1 cm apart, else the first camera's viewing axis; a negative distance puts
/// the pair behind.
/// Non-finite distances are skipped; an empty `real` gives none.
pub fn pseudo_pairs(
    real: &[(Camera, Camera)],
    ahead: &[Camera],
    distances: &[f32],
) -> Vec<PseudoPair> {
    let Some(&(first_left, first_right)) = real.first() else {
        return Vec::new();
    };
    // The rig's offset in the left camera's frame (world-to-camera rotation applied).
    let offset = first_left.rotation * (first_right.position - first_left.position);
    let pair = |left: Camera| PseudoPair {
        left,
        right: Camera {
            position: left.position + left.rotation.transpose() * offset,
            ..left
        },
    };
    let wanted = distances.iter().filter(|d| d.is_finite()).count();
    if !ahead.is_empty() {
        let m = ahead.len();
        let mut picked: Vec<usize> = (1..=wanted).map(|k| (k * m).div_ceil(wanted) - 1).collect();
        picked.dedup();
        return picked.into_iter().map(|i| pair(ahead[i])).collect();
    }
    let last_left = real[real.len() - 1].0;
    let travelled = last_left.position - first_left.position;
    let direction = if travelled.length() > 0.01 {
        travelled.normalize()
    } else {
        // The camera's +z axis in the bin frame (row 2 of the world-to-camera rotation).
        first_left.rotation.transpose() * Vec3::Z
    };
    distances
        .iter()
        .filter(|d| d.is_finite())
        .map(|&d| {
            pair(Camera {
                position: last_left.position + direction * d,
                ..last_left
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;
    use renderer::Intrinsics;

    fn rig_at(rotation: Quat, position: Vec3) -> (Camera, Camera) {
        let k = Intrinsics::from_hfov(64, 16, 90.0);
        let left = Camera::from_camera_to_world(k, rotation, position);
        let right = Camera::from_camera_to_world(k, rotation, position + rotation * Vec3::X * 0.6);
        (left, right)
    }

    #[test]
    fn with_known_poses_the_pairs_sit_evenly_up_to_the_last_with_the_rigs_baseline() {
        let turn = Quat::from_rotation_y(0.3);
        let real = [rig_at(Quat::IDENTITY, Vec3::ZERO)];
        let ahead: Vec<Camera> = (1..=5)
            .map(|i| rig_at(turn, Vec3::new(0.0, 0.0, 2.0 * i as f32)).0)
            .collect();
        let pairs = pseudo_pairs(&real, &ahead, &[4.0, 100.0]);
        assert_eq!(pairs.len(), 2);
        assert_eq!(pairs[0].left, ahead[2]);
        assert_eq!(pairs[1].left, ahead[4]);
        for p in &pairs {
            // The right camera is 0.6 m along the pseudo left camera's own x axis.
            let expected = p.left.position + turn * Vec3::X * 0.6;
            assert!((p.right.position - expected).length() < 1e-5);
            assert_eq!(p.right.rotation, p.left.rotation);
        }
        // One entry: the last pose; three: evenly spaced; one frame ahead: one pair; no
        // entries: none.
        assert_eq!(pseudo_pairs(&real, &ahead, &[8.0])[0].left, ahead[4]);
        let three: Vec<Camera> = pseudo_pairs(&real, &ahead, &[1.0, 2.0, f32::NAN, 3.0])
            .iter()
            .map(|p| p.left)
            .collect();
        assert_eq!(three, [ahead[1], ahead[3], ahead[4]]);
        assert_eq!(pseudo_pairs(&real, &ahead[..1], &[4.0, 8.0]).len(), 1);
        assert!(pseudo_pairs(&real, &ahead, &[]).is_empty());
    }

    #[test]
    fn without_poses_the_pairs_go_ahead_along_the_trajectory_far_from_the_origin() {
        let far = Vec3::new(1e5, -3.0, 2e4);
        let turn = Quat::from_rotation_y(-1.2);
        let one = [rig_at(turn, far)];
        let pairs = pseudo_pairs(&one, &[], &[4.0, 8.0, f32::NAN, -1.0]);
        assert_eq!(pairs.len(), 3);
        let forward = turn * Vec3::Z;
        for (p, d) in pairs.iter().zip([4.0, 8.0, -1.0]) {
            let moved = p.left.position - far;
            assert!((moved - forward * d).length() < 0.02, "{moved:?}");
            assert!((p.right.position - p.left.position).length() - 0.6 < 1e-2);
        }
        // With two real pairs, "ahead" is the way the car went, from the last real pair.
        let two = [rig_at(turn, far), rig_at(turn, far + Vec3::X * 3.0)];
        let pairs = pseudo_pairs(&two, &[], &[5.0]);
        let moved = pairs[0].left.position - (far + Vec3::X * 3.0);
        assert!((moved - Vec3::X * 5.0).length() < 0.02, "{moved:?}");
        assert!(pseudo_pairs(&[], &[], &[1.0]).is_empty());
    }
}
