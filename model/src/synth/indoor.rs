//! What the indoor scenes (a desk, a room) share: the handheld camera path, the indoor light,
//! surface finishes drawn from the photo bank or value noise, and the enclosure (floor,
//! walls, ceiling) every ray ends on, so no pixel sees the sky.
//!
//! Indoor frames: x right and y forward of the camera's mean view, z up, the floor at
//! z = 0. Everything is drawn from ChaCha streams of the sequence seed, so equal seeds give
//! equal scenes.

use std::f64::consts::TAU;

use glam::{DAffine3, DMat3, DVec2, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::primitives::Shape;
use super::randomise::{log_range, range, Randomisation};
use super::scene::Object;
use super::shading::{Finish, Material, Palette, PhotoSurface, SurfaceClass};

/// Thickness of walls, floor and ceiling slabs, metres.
const SLAB: f64 = 0.1;

/// An indoor scene: its solids and the camera's path through them.
#[derive(Clone, Debug)]
pub struct IndoorScene {
    /// Every solid, enclosure included.
    pub objects: Vec<Object>,
    /// The left camera's motion.
    pub path: HandheldPath,
}

/// One smooth periodic motion: `amplitude * sin(omega * i + phase)` at frame `i`.
#[derive(Clone, Copy, Debug)]
struct Wave {
    amplitude: f64,
    omega: f64,
    phase: f64,
}

impl Wave {
    /// A wave of `amplitude` whose peak speed is `speed` per frame.
    fn new(rng: &mut ChaCha8Rng, amplitude: f64, speed: f64) -> Self {
        Self {
            amplitude,
            omega: speed / amplitude.max(1e-9),
            phase: rng.random_range(0.0..TAU),
        }
    }

    fn at(&self, i: f64) -> f64 {
        self.amplitude * (self.omega * i + self.phase).sin()
    }
}

/// A handheld (or arm-mounted) camera: a Lissajous drift of a few centimetres per frame
/// around a mean position, and small slow rotations around a mean heading and pitch. It
/// stays near its mean forever, so a sequence of any length stays inside its scene.
#[derive(Clone, Copy, Debug)]
pub struct HandheldPath {
    centre: DVec3,
    drift: [Wave; 3],
    heading: f64,
    pitch: f64,
    /// Yaw, pitch and roll wobbles, radians.
    turn: [Wave; 3],
}

/// How a [`HandheldPath`] is drawn: where it is centred, how far and fast it drifts and
/// turns.
pub struct PathRanges {
    /// Mean camera position.
    pub centre: DVec3,
    /// Mean heading (radians from +x towards +y) and downward pitch (radians).
    pub heading_pitch: (f64, f64),
    /// Drift amplitude along x, y, z, metres.
    pub amplitude: DVec3,
    /// Peak drift speed, metres per frame.
    pub speed: (f64, f64),
    /// Largest wobble of yaw, pitch and roll, radians.
    pub wobble: f64,
}

impl HandheldPath {
    /// A path drawn from `rng` within `ranges`.
    pub fn new(rng: &mut ChaCha8Rng, ranges: &PathRanges) -> Self {
        let speed = range(rng, ranges.speed);
        let drift = [0, 1, 2].map(|k| {
            // Each axis at its own pace: the fastest moves at `speed`.
            let pace = rng.random_range(0.5..1.0);
            Wave::new(rng, ranges.amplitude[k], speed * pace)
        });
        let turn = [1.0, 0.6, 0.3].map(|share| {
            let amplitude = ranges.wobble * share * rng.random_range(0.4..1.0);
            let omega = rng.random_range(0.04..0.15);
            Wave::new(rng, amplitude, amplitude * omega)
        });
        Self {
            centre: ranges.centre,
            drift,
            heading: ranges.heading_pitch.0,
            pitch: ranges.heading_pitch.1,
            turn,
        }
    }

    /// Left camera to world (OpenCV axes: x right, y down, z forward) at frame `i`.
    pub fn pose(&self, i: usize) -> DAffine3 {
        let t = i as f64;
        let position = self.centre + DVec3::from_array(self.drift.map(|w| w.at(t)));
        let heading = self.heading + self.turn[0].at(t);
        let pitch = self.pitch + self.turn[1].at(t);
        let roll = self.turn[2].at(t);
        let (ch, sh) = (heading.cos(), heading.sin());
        let (cp, sp) = (pitch.cos(), pitch.sin());
        let forward = DVec3::new(ch * cp, sh * cp, -sp);
        let level_right = DVec3::new(sh, -ch, 0.0);
        let level_down = forward.cross(level_right);
        let (cr, sr) = (roll.cos(), roll.sin());
        let right = level_right * cr + level_down * sr;
        let down = forward.cross(right);
        DAffine3::from_mat3_translation(DMat3::from_cols(right, down, forward), position)
    }

    /// The horizontal direction the camera looks along on average (for shadow culling).
    pub fn tangent(&self) -> DVec2 {
        DVec2::new(self.heading.cos(), self.heading.sin())
    }
}

/// The indoor light, as a [`Palette`]: one key light from above (a lamp or a window's sun)
/// with soft ambient light, no haze. Randomised scenes get any light colour and level.
pub fn lighting(rng: &mut ChaCha8Rng, randomise: Option<&Randomisation>) -> Palette {
    let mut palette = Palette::new(rng);
    let azimuth = rng.random_range(0.0..TAU);
    let elevation = rng.random_range(40.0f64..85.0).to_radians();
    palette.sun_dir = DVec3::new(
        azimuth.cos() * elevation.cos(),
        azimuth.sin() * elevation.cos(),
        elevation.sin(),
    );
    let (warmth, key, fill) = match randomise {
        Some(_) => (
            rng.random_range(-0.25..0.25),
            rng.random_range(0.15..0.6),
            rng.random_range(0.25..0.55),
        ),
        None => (
            rng.random_range(-0.08..0.12),
            rng.random_range(0.3..0.5),
            rng.random_range(0.35..0.5),
        ),
    };
    palette.sun = DVec3::new(1.0 + warmth, 0.97, 1.0 - warmth) * key;
    palette.ambient = DVec3::new(1.0 + 0.3 * warmth, 1.0, 1.0 - 0.3 * warmth) * fill;
    palette.haze = 1e9;
    // What a ray that leaves the enclosure would see (none does): a dim grey.
    palette.zenith = DVec3::splat(0.3);
    palette.horizon = DVec3::splat(0.3);
    palette
}

/// Draws surface finishes: photo textures with the scene's probability, else a colour with
/// value-noise grain at a cell size fit for the distance it is seen from.
pub struct Finishes {
    photo_probability: f64,
    any_colour: bool,
}

impl Finishes {
    /// Finishes for a scene randomised by `randomise` (any colour, its photo probability),
    /// or for a plain one (colours near each class's own, photos half the time).
    pub fn new(rng: &mut ChaCha8Rng, randomise: Option<&Randomisation>) -> Self {
        match randomise {
            Some(r) => Self {
                photo_probability: r.photo_probability.clamp(0.0, 1.0),
                any_colour: rng.random_bool(r.colour_probability.clamp(0.0, 1.0)),
            },
            None => Self {
                photo_probability: 0.5,
                any_colour: false,
            },
        }
    }

    /// A finish of `class` around colour `base`, its grain's largest cell `cell` metres, a
    /// photo's period drawn from `period` metres.
    pub fn draw(
        &self,
        rng: &mut ChaCha8Rng,
        class: SurfaceClass,
        base: DVec3,
        cell: f64,
        period: (f64, f64),
    ) -> Finish {
        let photo = rng
            .random_bool(self.photo_probability)
            .then(|| PhotoSurface::draw(rng, period));
        let base = match self.any_colour {
            true => DVec3::new(
                rng.random_range(0.05..0.9),
                rng.random_range(0.05..0.9),
                rng.random_range(0.05..0.9),
            ),
            false => jitter(rng, base, 0.08),
        };
        Finish {
            class,
            base,
            grain: rng.random_range(0.5..1.1),
            cell: cell * rng.random_range(0.6..1.6),
            seed: rng.random(),
            photo,
        }
    }
}

/// `base` moved by up to `amount` per channel, kept in [0.03, 0.92].
pub fn jitter(rng: &mut ChaCha8Rng, base: DVec3, amount: f64) -> DVec3 {
    (base + DVec3::from_array([0; 3].map(|_| rng.random_range(-amount..amount))))
        .clamp(DVec3::splat(0.03), DVec3::splat(0.92))
}

/// A box with its base face centred at `centre`, axis-aligned (`yaw` = 0) or yawed.
pub fn block(centre: DVec3, half: DVec3, yaw: f64) -> Shape {
    Shape::Box {
        centre,
        axis: (yaw.cos(), yaw.sin()),
        half,
    }
}

/// The inside extent of an enclosure: x in `[-half_width, half_width]`, y in
/// `[back, front]`, z in `[0, height]`.
#[derive(Clone, Copy, Debug)]
pub struct Extent {
    /// Half the room's width, metres.
    pub half_width: f64,
    /// y of the wall behind the camera.
    pub back: f64,
    /// y of the wall the camera faces.
    pub front: f64,
    /// Floor to ceiling, metres.
    pub height: f64,
}

/// The enclosure's floor, ceiling and four walls (none casts shadows), with finishes drawn
/// from `finishes`; the grain cells suit surfaces seen from a metre or more.
pub fn enclosure(rng: &mut ChaCha8Rng, finishes: &Finishes, e: &Extent) -> Vec<Object> {
    let floor_colour = [
        DVec3::new(0.45, 0.32, 0.2),
        DVec3::new(0.6, 0.58, 0.55),
        DVec3::new(0.3, 0.3, 0.32),
    ][rng.random_range(0..3)];
    let floor = finishes.draw(rng, SurfaceClass::Floor, floor_colour, 0.4, (0.5, 2.0));
    let wall_colour = [
        DVec3::new(0.82, 0.8, 0.74),
        DVec3::new(0.7, 0.75, 0.8),
        DVec3::new(0.8, 0.7, 0.6),
    ][rng.random_range(0..3)];
    let wall = finishes.draw(rng, SurfaceClass::Wall, wall_colour, 0.6, (0.6, 3.0));
    let ceiling = finishes.draw(
        rng,
        SurfaceClass::Ceiling,
        DVec3::splat(0.85),
        0.8,
        (1.0, 3.0),
    );
    let (hx, mid_y, hy) = (
        e.half_width,
        0.5 * (e.back + e.front),
        0.5 * (e.front - e.back),
    );
    let span_x = hx + 2.0 * SLAB;
    let span_y = hy + 2.0 * SLAB;
    let wall_half_z = 0.5 * e.height + SLAB;
    let slabs = [
        // Floor and ceiling.
        (
            DVec3::new(0.0, mid_y, -2.0 * SLAB),
            DVec3::new(span_x, span_y, SLAB),
            floor,
        ),
        (
            DVec3::new(0.0, mid_y, e.height),
            DVec3::new(span_x, span_y, SLAB),
            ceiling,
        ),
        // Walls ahead of and behind the camera, then left and right.
        (
            DVec3::new(0.0, e.front + SLAB, -SLAB),
            DVec3::new(span_x, SLAB, wall_half_z),
            wall,
        ),
        (
            DVec3::new(0.0, e.back - SLAB, -SLAB),
            DVec3::new(span_x, SLAB, wall_half_z),
            wall,
        ),
        (
            DVec3::new(-hx - SLAB, mid_y, -SLAB),
            DVec3::new(SLAB, span_y, wall_half_z),
            wall,
        ),
        (
            DVec3::new(hx + SLAB, mid_y, -SLAB),
            DVec3::new(SLAB, span_y, wall_half_z),
            wall,
        ),
    ];
    slabs
        .into_iter()
        .map(|(centre, half, finish)| {
            Object::backdrop(block(centre, half, 0.0), Material::Finish(finish))
        })
        .collect()
}

/// Pictures and windows on the wall the camera faces (`y = front`) and on the side walls:
/// thin panels 1 cm proud of the wall, photo-textured pictures or bright window panes.
pub fn wall_panels(
    rng: &mut ChaCha8Rng,
    finishes: &Finishes,
    e: &Extent,
    count: usize,
) -> Vec<Object> {
    let mut out = Vec::with_capacity(count);
    for _ in 0..count {
        let window = rng.random_bool(0.3);
        let (w, h) = match window {
            true => (rng.random_range(0.6..1.4f64), rng.random_range(0.8..1.4f64)),
            false => (rng.random_range(0.2..0.9f64), rng.random_range(0.2..0.7f64)),
        };
        let bottom = match window {
            true => rng.random_range(0.7..1.0f64),
            false => rng.random_range(1.0..1.6f64),
        }
        .min((e.height - h - 0.1).max(0.0));
        let finish = match window {
            true => Finish {
                class: SurfaceClass::Window,
                base: log_range(rng, (0.75, 0.95)) * DVec3::new(0.95, 0.98, 1.0),
                grain: 0.15,
                cell: 0.3,
                seed: rng.random(),
                photo: None,
            },
            false => Finish {
                photo: Some(PhotoSurface::draw(rng, (w.max(h), 2.0 * w.max(h)))),
                ..finishes.draw(
                    rng,
                    SurfaceClass::Picture,
                    DVec3::splat(0.5),
                    0.1,
                    (0.3, 1.0),
                )
            },
        };
        let depth = 0.01;
        let shape = match rng.random_range(0..3) {
            0 => {
                let x = rng.random_range(-1.0..1.0) * (e.half_width - 0.5 * w).max(0.0);
                block(
                    DVec3::new(x, e.front - 0.5 * depth, bottom),
                    DVec3::new(0.5 * w, depth, 0.5 * h),
                    0.0,
                )
            }
            side => {
                let sign = if side == 1 { -1.0 } else { 1.0 };
                let span = 0.5 * (e.front - e.back);
                let y = 0.5 * (e.front + e.back) + rng.random_range(-1.0..1.0) * (span - 0.5 * w);
                block(
                    DVec3::new(sign * (e.half_width - 0.5 * depth), y, bottom),
                    DVec3::new(depth, 0.5 * w, 0.5 * h),
                    0.0,
                )
            }
        };
        out.push(Object::backdrop(shape, Material::Finish(finish)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn a_handheld_path_moves_centimetres_and_turns_degrees() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let path = HandheldPath::new(
            &mut rng,
            &PathRanges {
                centre: DVec3::new(0.0, 0.0, 1.0),
                heading_pitch: (0.5 * std::f64::consts::PI, 0.6),
                amplitude: DVec3::new(0.2, 0.1, 0.05),
                speed: (0.01, 0.03),
                wobble: 0.05,
            },
        );
        for i in 0..300 {
            let (a, b) = (path.pose(i), path.pose(i + 1));
            let step = (b.translation - a.translation).length();
            assert!(step < 0.031 * 3f64.sqrt(), "frame {i}: step {step}");
            let r = a.matrix3;
            assert!((r.transpose() * r - DMat3::IDENTITY).abs_diff_eq(DMat3::ZERO, 1e-12));
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            // Looking forward (+y) and down, within the wobble.
            assert!(r.z_axis.y > 0.7 && r.z_axis.z < -0.4, "{:?}", r.z_axis);
            assert!(
                (a.translation - DVec3::new(0.0, 0.0, 1.0))
                    .abs()
                    .max_element()
                    <= 0.2
            );
        }
    }
}
