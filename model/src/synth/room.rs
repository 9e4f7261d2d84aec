//! The room: a handheld camera at head or robot height walking slowly through a furnished
//! room whose floor, walls and ceiling lie 1-10 m away: cabinets, shelves and sofas along
//! the walls, a table and lamps standing free, a rug, pictures and windows.

use std::f64::consts::FRAC_PI_2;

use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::config::SynthConfig;
use super::indoor::{
    block, enclosure, wall_panels, Extent, Finishes, HandheldPath, IndoorScene, PathRanges,
};
use super::primitives::Shape;
use super::randomise::range;
use super::scene::Object;
use super::shading::{Material, SurfaceClass};

/// The distance range (metres, from the camera's mean position to the wall it faces) a room
/// draws from.
pub const VIEW_DISTANCE_M: (f64, f64) = (2.5, 8.5);

/// Nearest a piece of furniture comes to the camera's mean position sideways, metres.
const CLEARANCE: f64 = 1.2;

/// Builds the room of `config` from `rng`.
pub fn build(rng: &mut ChaCha8Rng, config: &SynthConfig) -> IndoorScene {
    let randomise = config.randomise.as_ref();
    let finishes = Finishes::new(rng, randomise);
    let far = config
        .view_distance_m
        .unwrap_or_else(|| range(rng, VIEW_DISTANCE_M));
    let half_width = range(rng, (1.6, 4.5));
    let height = range(rng, (2.4, 3.4));
    let side_room = (half_width - 1.6).max(0.0);
    let camera = DVec3::new(
        range(rng, (-side_room, side_room)),
        0.0,
        range(rng, (1.0, (height - 0.7).min(1.7))),
    );
    let extent = Extent {
        half_width,
        back: -range(rng, (0.8, 2.5)),
        front: far,
        height,
    };
    let sway = (half_width - 1.5 - camera.x.abs()).clamp(0.02, 0.6);
    let ranges = PathRanges {
        centre: camera,
        heading_pitch: (FRAC_PI_2, range(rng, (0.0, 12f64.to_radians()))),
        amplitude: DVec3::new(
            range(rng, (0.02, sway)),
            range(rng, (0.3, (0.25 * far).clamp(0.31, 0.8))),
            range(rng, (0.01, 0.05)),
        ),
        speed: (0.02, 0.06),
        wobble: 8f64.to_radians(),
    };
    let path = HandheldPath::new(rng, &ranges);
    let mut objects = enclosure(rng, &finishes, &extent);
    let panels = rng.random_range(1..5);
    objects.extend(wall_panels(rng, &finishes, &extent, panels));
    let furnish = Furnish {
        finishes: &finishes,
        extent,
        camera,
    };
    for wall in [Wall::Left, Wall::Right, Wall::Front] {
        for _ in 0..rng.random_range(0..3) {
            if let Some(piece) = furnish.against(rng, wall) {
                objects.push(piece);
            }
        }
    }
    if far > 3.0 {
        furnish.table(rng, &mut objects);
    }
    for _ in 0..rng.random_range(0..3) {
        objects.push(furnish.standing(rng));
    }
    if rng.random_bool(0.5) {
        objects.push(furnish.rug(rng));
    }
    IndoorScene { objects, path }
}

/// The wall a piece of furniture stands against.
#[derive(Clone, Copy)]
enum Wall {
    Left,
    Right,
    Front,
}

/// Draws furniture for one room.
struct Furnish<'a> {
    finishes: &'a Finishes,
    extent: Extent,
    camera: DVec3,
}

impl Furnish<'_> {
    fn finish(&self, rng: &mut ChaCha8Rng) -> Material {
        let colour = [
            DVec3::new(0.5, 0.35, 0.22),
            DVec3::new(0.85, 0.85, 0.82),
            DVec3::new(0.25, 0.3, 0.4),
            DVec3::new(0.55, 0.2, 0.15),
        ][rng.random_range(0..4)];
        Material::Finish(
            self.finishes
                .draw(rng, SurfaceClass::Furniture, colour, 0.25, (0.3, 1.5)),
        )
    }

    /// A cabinet, shelf or sofa against `wall`, kept `CLEARANCE` sideways from the camera
    /// (`None` when the room is too narrow for one there).
    fn against(&self, rng: &mut ChaCha8Rng, wall: Wall) -> Option<Object> {
        let e = &self.extent;
        let tall = rng.random_range(0.4..2.0f64).min(e.height - 0.2);
        let width = rng.random_range(0.5..2.0);
        let shape = match wall {
            Wall::Front => {
                let depth = rng.random_range(0.3..0.9f64).min(0.4 * (e.front - 1.0));
                if depth < 0.2 {
                    return None;
                }
                let x = rng.random_range(-1.0..1.0) * (e.half_width - 0.5 * width).max(0.0);
                block(
                    DVec3::new(x, e.front - 0.5 * depth, 0.0),
                    DVec3::new(0.5 * width, 0.5 * depth, 0.5 * tall),
                    0.0,
                )
            }
            Wall::Left | Wall::Right => {
                let sign = if matches!(wall, Wall::Left) {
                    -1.0
                } else {
                    1.0
                };
                let room = e.half_width - sign * self.camera.x - CLEARANCE;
                let depth = rng.random_range(0.3..0.9f64).min(room);
                let first = 1.0 + 0.5 * width;
                if depth < 0.2 || e.front - 0.5 * width <= first {
                    return None;
                }
                let y = rng.random_range(first..e.front - 0.5 * width);
                block(
                    DVec3::new(sign * (e.half_width - 0.5 * depth), y, 0.0),
                    DVec3::new(0.5 * depth, 0.5 * width, 0.5 * tall),
                    0.0,
                )
            }
        };
        Some(Object::new(shape, self.finish(rng)))
    }

    /// A point on the floor at least 1.8 m ahead of the camera and inside the room.
    fn spot(&self, rng: &mut ChaCha8Rng, margin: f64) -> DVec3 {
        let e = &self.extent;
        let x = rng.random_range(-1.0..1.0) * (e.half_width - margin).max(0.0);
        let y = range(rng, (1.8 + margin, (e.front - margin).max(1.8 + margin)));
        DVec3::new(x, y, 0.0)
    }

    /// A table (a top on four legs) standing free ahead of the camera.
    fn table(&self, rng: &mut ChaCha8Rng, out: &mut Vec<Object>) {
        let half = DVec3::new(
            rng.random_range(0.4..0.9),
            rng.random_range(0.35..0.6),
            0.02,
        );
        let at = self.spot(rng, half.x.max(half.y) + 0.1);
        let top_z = rng.random_range(0.45..0.8);
        let material = self.finish(rng);
        let top = block(at + DVec3::Z * (top_z - 0.04), half, 0.0);
        out.push(Object::new(top, material));
        for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
            let leg = Shape::Cylinder {
                base: at + DVec3::new(sx * (half.x - 0.05), sy * (half.y - 0.05), 0.0),
                radius: 0.025,
                height: top_z - 0.04,
            };
            out.push(Object::new(leg, material));
        }
    }

    /// A standing lamp (a pole), a bin (a cylinder) or a pouf (an ellipsoid).
    fn standing(&self, rng: &mut ChaCha8Rng) -> Object {
        let material = self.finish(rng);
        let shape = match rng.random_range(0..3) {
            0 => Shape::Cylinder {
                base: self.spot(rng, 0.3),
                radius: rng.random_range(0.02..0.05),
                height: rng.random_range(1.2..1.8f64).min(self.extent.height - 0.2),
            },
            1 => Shape::Cylinder {
                base: self.spot(rng, 0.4),
                radius: rng.random_range(0.12..0.3),
                height: rng.random_range(0.3..0.7),
            },
            _ => {
                let r = DVec3::new(
                    rng.random_range(0.2..0.45),
                    rng.random_range(0.2..0.45),
                    rng.random_range(0.15..0.3),
                );
                Shape::Ellipsoid {
                    centre: self.spot(rng, r.x.max(r.y)) + DVec3::Z * r.z,
                    radii: r,
                }
            }
        };
        Object::new(shape, material)
    }

    /// A thin rug on the floor ahead of the camera.
    fn rug(&self, rng: &mut ChaCha8Rng) -> Object {
        let half = DVec3::new(
            rng.random_range(0.6..1.5),
            rng.random_range(0.5..1.2),
            0.004,
        );
        let at = self.spot(rng, 0.2);
        let finish = self.finishes.draw(
            rng,
            SurfaceClass::Floor,
            DVec3::new(0.6, 0.3, 0.25),
            0.2,
            (0.4, 1.5),
        );
        Object::backdrop(
            block(at, half, rng.random_range(0.0..std::f64::consts::PI)),
            Material::Finish(finish),
        )
    }
}
