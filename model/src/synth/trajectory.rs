//! The road's centreline (smoothly varying curvature, arc-length parametrised) and the
//! vehicle's motion along it (10 Hz frames, smoothly varying speed between 3 and 12 m/s).

use std::f64::consts::TAU;

use glam::{DAffine3, DMat3, DVec2, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Spacing of the tabulated centreline, metres.
const TABLE_STEP: f64 = 1.0;
/// Arc length at which the first frame sits, so the world extends behind it too.
pub const START_ARC: f64 = 200.0;
/// Frame period in seconds (10 Hz).
pub const FRAME_DT: f64 = 0.1;
/// Camera height above the road, metres.
pub const CAMERA_HEIGHT: f64 = 1.55;
/// Lateral offset of the ego camera from the centreline (negative: right lane).
pub const EGO_LATERAL: f64 = -1.75;

/// The road centreline: heading is a closed-form integral of a sum of sinusoidal
/// curvatures; positions are tabulated once (midpoint rule) and interpolated.
#[derive(Clone, Debug)]
pub struct Road {
    heading0: f64,
    waves: [(f64, f64, f64); 2],
    points: Vec<DVec2>,
}

impl Road {
    /// A road of at least `length` metres drawn from `rng`.
    pub fn new(rng: &mut ChaCha8Rng, length: f64) -> Self {
        let heading0 = rng.random_range(0.0..TAU);
        let waves = [
            (
                rng.random_range(0.003..0.010),
                TAU / rng.random_range(150.0..320.0),
                rng.random_range(0.0..TAU),
            ),
            (
                rng.random_range(0.001..0.005),
                TAU / rng.random_range(60.0..120.0),
                rng.random_range(0.0..TAU),
            ),
        ];
        let mut road = Self {
            heading0,
            waves,
            points: Vec::new(),
        };
        let n = (length / TABLE_STEP).ceil() as usize + 2;
        let mut p = DVec2::ZERO;
        road.points.reserve(n);
        for i in 0..n {
            road.points.push(p);
            let mid = road.heading((i as f64 + 0.5) * TABLE_STEP);
            p += DVec2::new(mid.cos(), mid.sin()) * TABLE_STEP;
        }
        road
    }

    /// Heading (radians, from world +x towards +y) at arc length `s`.
    pub fn heading(&self, s: f64) -> f64 {
        self.heading0
            + self
                .waves
                .iter()
                .map(|&(a, w, phi)| a / w * (phi.cos() - (w * s + phi).cos()))
                .sum::<f64>()
    }

    /// Unit tangent at `s`.
    pub fn tangent(&self, s: f64) -> DVec2 {
        let h = self.heading(s);
        DVec2::new(h.cos(), h.sin())
    }

    /// Centreline point at `s` (extrapolated along the end tangents outside the table).
    pub fn point(&self, s: f64) -> DVec2 {
        let last = (self.points.len() - 1) as f64 * TABLE_STEP;
        if s <= 0.0 {
            return self.points[0] + self.tangent(0.0) * s;
        }
        if s >= last {
            return self.points[self.points.len() - 1] + self.tangent(last) * (s - last);
        }
        let x = s / TABLE_STEP;
        let i = x.floor() as usize;
        let f = x - i as f64;
        self.points[i].lerp(self.points[i + 1], f)
    }

    /// Road coordinates (arc length, lateral offset to the left) of a ground point, found by
    /// a few projection steps starting from arc length `guess`.
    pub fn project(&self, p: DVec2, guess: f64) -> (f64, f64) {
        let mut s = guess;
        for _ in 0..3 {
            s += (p - self.point(s)).dot(self.tangent(s));
        }
        let t = self.tangent(s);
        (s, (p - self.point(s)).dot(DVec2::new(-t.y, t.x)))
    }

    /// A world point on the road at arc length `s`, `lateral` metres left, height `z`.
    pub fn world(&self, s: f64, lateral: f64, z: f64) -> DVec3 {
        let t = self.tangent(s);
        let p = self.point(s) + DVec2::new(-t.y, t.x) * lateral;
        DVec3::new(p.x, p.y, z)
    }
}

/// The ego motion: arc length per frame from a smooth speed profile.
#[derive(Clone, Debug)]
pub struct Trajectory {
    arcs: Vec<f64>,
    pitch: f64,
    speed: SpeedProfile,
}

/// Speed over time: a mean plus two sinusoids, clamped to [3, 12] m/s.
#[derive(Clone, Copy, Debug)]
struct SpeedProfile {
    amplitudes: (f64, f64),
    phases: (f64, f64),
    periods: (f64, f64),
}

impl SpeedProfile {
    fn at(&self, t: f64) -> f64 {
        let (a1, a2) = self.amplitudes;
        let wave1 = a1 * (TAU * t / self.periods.0 + self.phases.0).sin();
        let wave2 = a2 * (TAU * t / self.periods.1 + self.phases.1).sin();
        (7.5 + wave1 + wave2).clamp(3.0, 12.0)
    }

    /// Distance travelled during frame interval `i` (midpoint rule).
    fn step(&self, i: usize) -> f64 {
        self.at((i as f64 + 0.5) * FRAME_DT) * FRAME_DT
    }
}

impl Trajectory {
    /// `frames` frames of motion drawn from `rng` (later frames are computed on demand).
    pub fn new(rng: &mut ChaCha8Rng, frames: u32) -> Self {
        let speed = SpeedProfile {
            amplitudes: (rng.random_range(1.5..3.0), rng.random_range(0.5..1.5)),
            phases: (rng.random_range(0.0..TAU), rng.random_range(0.0..TAU)),
            periods: (rng.random_range(25.0..50.0), rng.random_range(8.0..16.0)),
        };
        let pitch = rng.random_range(0.5f64..2.0).to_radians();
        let mut arcs = Vec::with_capacity(frames as usize + 1);
        let mut s = START_ARC;
        for i in 0..=frames as usize {
            arcs.push(s);
            s += speed.step(i);
        }
        Self { arcs, pitch, speed }
    }

    /// Arc length of frame `i`; frames past the tabulated ones continue the same motion.
    pub fn arc(&self, i: usize) -> f64 {
        if let Some(&s) = self.arcs.get(i) {
            return s;
        }
        let last = self.arcs.len() - 1;
        (last..i).fold(self.arcs[last], |s, k| s + self.speed.step(k))
    }

    /// The last frame's arc length.
    pub fn end_arc(&self) -> f64 {
        self.arcs[self.arcs.len() - 1]
    }

    /// Left camera to world (OpenCV axes) at frame `i`: right lane, camera height above the
    /// road, looking along the road with the sequence's downward pitch.
    pub fn pose(&self, road: &Road, i: usize) -> DAffine3 {
        let s = self.arc(i);
        let h = road.heading(s);
        let (cp, sp) = (self.pitch.cos(), self.pitch.sin());
        let forward = DVec3::new(h.cos() * cp, h.sin() * cp, -sp);
        let right = DVec3::new(h.sin(), -h.cos(), 0.0);
        let down = forward.cross(right);
        DAffine3::from_mat3_translation(
            DMat3::from_cols(right, down, forward),
            road.world(s, EGO_LATERAL, CAMERA_HEIGHT),
        )
    }
}
