//! The street's furniture, laid out procedurally per road segment: buildings on both sides
//! (some plain walls, some gaps), parked cars, poles, trees, and oncoming cars driving in the
//! opposite lane. Each segment's content depends only on (seed, segment index), so any
//! stretch of road can be built on demand and a frame only builds what lies near it.

use glam::DVec3;
use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::primitives::Shape;
use super::randomise::Randomisation;
use super::shading::{FacadeStyle, Material, Palette, PhotoSurface, KERB, ROAD_HALF, SIDEWALK};
use super::textures::mix64;
use super::trajectory::{Road, EGO_LATERAL};

/// Length of one layout segment along the road, metres.
pub const SEGMENT: f64 = 15.0;
/// Speed of oncoming traffic, m/s.
pub const ONCOMING_SPEED: f64 = 8.0;

/// One solid of the scene with its material and bounding sphere.
#[derive(Clone, Copy, Debug)]
pub struct Object {
    /// Geometry.
    pub shape: Shape,
    /// Look.
    pub material: Material,
    /// Bounding sphere centre.
    pub centre: DVec3,
    /// Bounding sphere radius.
    pub radius: f64,
    /// Whether it can hide the light from other surfaces (an enclosure's walls and ceiling
    /// do not: the light is inside the room).
    pub casts_shadow: bool,
}

impl Object {
    /// A solid that casts shadows.
    pub(super) fn new(shape: Shape, material: Material) -> Self {
        let (centre, radius) = shape.bounds();
        Self {
            shape,
            material,
            centre,
            radius,
            casts_shadow: true,
        }
    }

    /// A solid that never hides the light (walls, ceilings, backdrops).
    pub(super) fn backdrop(shape: Shape, material: Material) -> Self {
        Self {
            casts_shadow: false,
            ..Self::new(shape, material)
        }
    }
}

/// A yawed box standing on the ground at road coordinates.
fn road_box(road: &Road, s: f64, lateral: f64, z: f64, half: DVec3, reverse: bool) -> Shape {
    let mut t = road.tangent(s);
    if reverse {
        t = -t;
    }
    Shape::Box {
        centre: road.world(s, lateral, z),
        axis: (t.x, t.y),
        half,
    }
}

/// Pushes a car (body and cabin) at road coordinates.
fn car(out: &mut Vec<Object>, road: &Road, s: f64, lateral: f64, paint: DVec3, reverse: bool) {
    let body = road_box(road, s, lateral, 0.18, DVec3::new(2.1, 0.88, 0.38), reverse);
    let cabin_s = s + if reverse { 0.25 } else { -0.25 };
    let cabin = road_box(
        road,
        cabin_s,
        lateral,
        0.94,
        DVec3::new(1.15, 0.8, 0.3),
        reverse,
    );
    out.push(Object::new(body, Material::CarBody(paint)));
    out.push(Object::new(cabin, Material::CarCabin(paint)));
}

/// The procedural street: road plus per-segment furniture.
#[derive(Clone, Debug)]
pub struct Street {
    seed: u64,
    /// Domain randomisation: photo facades and floating objects, when set.
    randomisation: Option<Randomisation>,
}

impl Street {
    /// The street of a sequence seed, randomised by `randomisation` if given.
    pub fn new(seed: u64, randomisation: Option<Randomisation>) -> Self {
        Self {
            seed,
            randomisation,
        }
    }

    fn rng(&self, salt: u64, segment: i64) -> ChaCha8Rng {
        ChaCha8Rng::seed_from_u64(mix64(self.seed ^ mix64(salt ^ mix64(segment as u64))))
    }

    /// All objects whose segment overlaps `[s - range, s + range]` at time `time` seconds.
    pub fn objects_near(
        &self,
        road: &Road,
        palette: &Palette,
        s: f64,
        range: f64,
        time: f64,
    ) -> Vec<Object> {
        let mut out = Vec::new();
        let first = ((s - range) / SEGMENT).floor() as i64;
        let last = ((s + range) / SEGMENT).ceil() as i64;
        for k in first..=last {
            self.static_segment(road, palette, k, &mut out);
        }
        // Oncoming cars of segment k sit at k * SEGMENT - speed * time.
        let shift = ONCOMING_SPEED * time;
        let first = ((s - range + shift) / SEGMENT).floor() as i64;
        let last = ((s + range + shift) / SEGMENT).ceil() as i64;
        for k in first..=last {
            let mut rng = self.rng(2, k);
            if rng.random_bool(0.35) {
                let at = (k as f64 + rng.random_range(0.0..1.0)) * SEGMENT - shift;
                let paint = palette.paints[rng.random_range(0..palette.paints.len())];
                car(&mut out, road, at, 1.75, paint, true);
            }
        }
        out
    }

    /// `style` with a photo wall, drawn from its own stream (so the plain generator's draws,
    /// and its drives, stay exactly as they were).
    fn photo_facade(&self, style: FacadeStyle, k: i64, side: f64) -> FacadeStyle {
        let Some(r) = self.randomisation else {
            return style;
        };
        let mut rng = self.rng(3 + (side > 0.0) as u64, k);
        let photo = rng
            .random_bool(r.photo_probability.clamp(0.0, 1.0))
            .then(|| PhotoSurface::draw(&mut rng, r.photo_period_m));
        FacadeStyle { photo, ..style }
    }

    /// FlyingThings3D-style floating objects: photo-textured boxes and ellipsoids hanging
    /// over the road and sidewalks, beside the camera's path at a clearance the camera
    /// passes closely, so the drive sees them from far down to a fraction of a metre.
    fn floaters(&self, road: &Road, k: i64, out: &mut Vec<Object>) {
        let Some(r) = self.randomisation else {
            return;
        };
        let mut rng = self.rng(5, k);
        let (lo, hi) = r.floaters_per_segment;
        let count = rng.random_range(lo.min(hi)..=hi.max(lo));
        for _ in 0..count {
            let size = rng.random_range(
                r.floater_size_m.0..r.floater_size_m.1.max(r.floater_size_m.0 + 1e-6),
            );
            let half = DVec3::new(
                size * rng.random_range(0.3..1.0),
                size * rng.random_range(0.3..1.0),
                size * rng.random_range(0.3..1.0),
            );
            let (c0, c1) = r.floater_clearance_m;
            let clearance = rng.random_range(c0..c1.max(c0 + 1e-6));
            let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let lateral = EGO_LATERAL + side * (clearance + half.x.hypot(half.y));
            let at = (k as f64 + rng.random_range(0.0..1.0)) * SEGMENT;
            let z = rng.random_range(0.0..2.2);
            let material = Material::Photo(PhotoSurface::draw(&mut rng, (0.3, 2.0)));
            let shape = if rng.random_bool(0.6) {
                let yaw = rng.random_range(0.0..std::f64::consts::TAU);
                Shape::Box {
                    centre: road.world(at, lateral, z),
                    axis: (yaw.cos(), yaw.sin()),
                    half,
                }
            } else {
                Shape::Ellipsoid {
                    centre: road.world(at, lateral, z + half.z),
                    radii: half,
                }
            };
            out.push(Object::new(shape, material));
        }
    }

    fn static_segment(&self, road: &Road, palette: &Palette, k: i64, out: &mut Vec<Object>) {
        self.floaters(road, k, out);
        let mut rng = self.rng(1, k);
        let s0 = k as f64 * SEGMENT;
        for side in [-1.0, 1.0] {
            // Buildings set back behind the sidewalk, or a gap with a lawn.
            if rng.random_bool(0.85) {
                let gap = rng.random_range(0.3..2.0);
                let depth = rng.random_range(8.0..14.0);
                let setback = rng.random_range(0.0..2.0);
                let height = rng.random_range(7.0..22.0);
                let lateral = side * (ROAD_HALF + KERB + SIDEWALK + setback + 0.5 * depth);
                let style = FacadeStyle {
                    wall: palette.walls[rng.random_range(0..palette.walls.len())],
                    glass: DVec3::new(0.1, 0.13, 0.17) * rng.random_range(0.7..1.4),
                    column: rng.random_range(2.4..3.8),
                    window_duty: rng.random_range(0.35..0.55),
                    storey: rng.random_range(2.9..3.6),
                    plain: rng.random_bool(0.15),
                    seed: rng.random(),
                    photo: None,
                };
                let style = self.photo_facade(style, k, side);
                let half = DVec3::new(0.5 * (SEGMENT - gap), 0.5 * depth, 0.5 * height);
                let shape = road_box(road, s0 + 0.5 * SEGMENT, lateral, 0.0, half, false);
                out.push(Object::new(shape, Material::Facade(style)));
            }
            // A parked car in the parking lane.
            if rng.random_bool(0.55) {
                let at = s0 + rng.random_range(2.5..12.5);
                let paint = palette.paints[rng.random_range(0..palette.paints.len())];
                car(out, road, at, side * (ROAD_HALF - 1.15), paint, side > 0.0);
            }
            // A pole near the kerb.
            if rng.random_bool(0.5) {
                let base = road.world(s0 + 1.5, side * (ROAD_HALF + KERB + 0.4), 0.0);
                let shape = Shape::Cylinder {
                    base,
                    radius: rng.random_range(0.07..0.14),
                    height: rng.random_range(5.0..8.0),
                };
                out.push(Object::new(shape, Material::Pole));
            }
            // A tree on the sidewalk.
            if rng.random_bool(0.45) {
                let at = s0 + rng.random_range(6.0..11.0);
                let lateral = side * (ROAD_HALF + KERB + 0.5 * SIDEWALK + 0.3);
                let trunk_h = rng.random_range(2.2..3.2);
                let base = road.world(at, lateral, 0.0);
                let trunk = Shape::Cylinder {
                    base,
                    radius: rng.random_range(0.12..0.22),
                    height: trunk_h + 1.0,
                };
                let r = rng.random_range(1.6..2.6);
                let canopy = Shape::Ellipsoid {
                    centre: base + DVec3::Z * (trunk_h + r * 0.9),
                    radii: DVec3::new(r, r, r * rng.random_range(1.0..1.35)),
                };
                let tint = DVec3::new(
                    rng.random_range(0.12..0.22),
                    rng.random_range(0.25..0.38),
                    rng.random_range(0.06..0.12),
                );
                out.push(Object::new(trunk, Material::Trunk));
                out.push(Object::new(canopy, Material::Canopy(tint)));
            }
        }
    }
}
