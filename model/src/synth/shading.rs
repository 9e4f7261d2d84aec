//! Looks: the per-sequence palette and lighting (sun, ambient, sky, haze), surface classes,
//! and the procedural albedo of every material (road with lane marks, kerb, sidewalk,
//! facades with windows, cars, poles, trees).

use glam::{DVec2, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::photos::PhotoBank;
use super::randomise::Randomisation;
use super::textures::{band, fbm, stripes};

/// What a pixel shows: the generator's semantic label, used to check scene content.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SurfaceClass {
    /// No surface (depth 0).
    Sky,
    /// Asphalt.
    Road,
    /// Painted lane markings.
    Marking,
    /// Kerb stones between road and sidewalk.
    Kerb,
    /// Paved sidewalk.
    Sidewalk,
    /// Grass or soil beyond the sidewalk.
    Verge,
    /// Building facade (wall with windows).
    Facade,
    /// A facade's window.
    Window,
    /// A plain, almost textureless wall.
    PlainWall,
    /// A parked or oncoming car.
    Car,
    /// A street pole.
    Pole,
    /// A tree trunk.
    Trunk,
    /// A tree canopy.
    Canopy,
    /// A floating object of the domain randomisation.
    Floater,
    /// An indoor floor.
    Floor,
    /// An indoor wall (or a desk's backdrop).
    Wall,
    /// A room's ceiling.
    Ceiling,
    /// A table: its top and legs.
    Table,
    /// A room's furniture: cabinets, shelves, sofas, lamps.
    Furniture,
    /// An object on a desk: a box, a can, a ball.
    Item,
    /// A hand (palm and fingers) resting on a desk.
    Hand,
    /// A picture hanging on a wall.
    Picture,
}

/// A photo texture on a surface (domain randomisation, [`super::photos`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotoSurface {
    /// Tile of the bank.
    pub tile: usize,
    /// The tile repeats every this many metres.
    pub period: f64,
    /// Per-channel albedo multiplier (material colour).
    pub tint: DVec3,
}

impl PhotoSurface {
    /// A photo surface drawn from `rng`: any tile, a period in `period` metres, a tint.
    pub fn draw(rng: &mut ChaCha8Rng, period: (f64, f64)) -> Self {
        Self {
            tile: rng.random_range(0..PhotoBank::get().len().max(1)),
            period: rng.random_range(period.0..period.1.max(period.0 + 1e-6)),
            tint: DVec3::new(
                rng.random_range(0.6..1.3),
                rng.random_range(0.6..1.3),
                rng.random_range(0.6..1.3),
            ),
        }
    }

    /// Albedo at surface coordinates (u, v) metres for a footprint of `w` metres.
    pub fn albedo(&self, u: f64, v: f64, w: f64) -> DVec3 {
        (PhotoBank::get().sample(self.tile, u, v, self.period, w) * self.tint)
            .clamp(DVec3::ZERO, DVec3::splat(0.95))
    }
}

/// An indoor surface: a base colour with value-noise grain, or a photo texture, and the
/// class it reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Finish {
    /// What the surface is.
    pub class: SurfaceClass,
    /// Albedo the grain varies around.
    pub base: DVec3,
    /// Relative amplitude of the grain (0: a flat colour).
    pub grain: f64,
    /// Largest noise cell of the grain, metres (finer octaves halve it).
    pub cell: f64,
    /// Noise seed.
    pub seed: u64,
    /// A photo texture replacing the grain, when set.
    pub photo: Option<PhotoSurface>,
}

impl Finish {
    /// Albedo at surface coordinates (u, v) metres for a footprint of `w` metres.
    pub fn albedo(&self, u: f64, v: f64, w: f64) -> DVec3 {
        match self.photo {
            Some(photo) => photo.albedo(u, v, w),
            None => (self.base * (1.0 + self.grain * fbm(self.seed, u, v, self.cell, 6, w)))
                .clamp(DVec3::splat(0.01), DVec3::splat(0.95)),
        }
    }
}

/// Half width of the carriageway (two 3.5 m lanes plus two 2.3 m parking lanes), metres.
pub const ROAD_HALF: f64 = 5.8;
/// Width of the kerb stones, metres.
pub const KERB: f64 = 0.3;
/// Width of each sidewalk, metres.
pub const SIDEWALK: f64 = 3.2;

/// How a facade looks: wall and window colours and the window grid.
#[derive(Clone, Copy, Debug)]
pub struct FacadeStyle {
    /// Wall albedo.
    pub wall: DVec3,
    /// Window glass albedo.
    pub glass: DVec3,
    /// Horizontal window period, metres.
    pub column: f64,
    /// Window width as a fraction of the period.
    pub window_duty: f64,
    /// Storey height, metres.
    pub storey: f64,
    /// No windows, hardly any texture (a low-texture wall).
    pub plain: bool,
    /// Noise seed of the wall.
    pub seed: u64,
    /// A photo texture replacing the wall's colour (domain randomisation).
    pub photo: Option<PhotoSurface>,
}

/// The surface an object is made of.
#[derive(Clone, Copy, Debug)]
pub enum Material {
    /// Building facade.
    Facade(FacadeStyle),
    /// Car body paint.
    CarBody(DVec3),
    /// Car cabin (glass with painted roof) over the given paint.
    CarCabin(DVec3),
    /// Metal pole.
    Pole,
    /// Tree bark.
    Trunk,
    /// Foliage of the given tint.
    Canopy(DVec3),
    /// A photo-textured floating object (domain randomisation).
    Photo(PhotoSurface),
    /// An indoor surface.
    Finish(Finish),
}

/// Per-sequence colours and light.
#[derive(Clone, Debug)]
pub struct Palette {
    /// Unit vector towards the sun (world, z up).
    pub sun_dir: DVec3,
    /// Sun radiance multiplying Lambert's cosine.
    pub sun: DVec3,
    /// Ambient (sky) light.
    pub ambient: DVec3,
    /// Sky colour at the zenith.
    pub zenith: DVec3,
    /// Sky colour at the horizon (also the haze colour).
    pub horizon: DVec3,
    /// Haze distance: contrast falls to 1/e over this many metres.
    pub haze: f64,
    /// Asphalt albedo.
    pub asphalt: DVec3,
    /// Sidewalk albedo.
    pub paving: DVec3,
    /// Verge albedo.
    pub verge: DVec3,
    /// Wall colours buildings pick from.
    pub walls: Vec<DVec3>,
    /// Car paints.
    pub paints: Vec<DVec3>,
    /// Noise seed of the ground.
    pub seed: u64,
    /// Photo textures of the road, sidewalk and verge (domain randomisation), replacing
    /// their procedural grain where set.
    pub ground_photos: [Option<PhotoSurface>; 3],
}

fn jitter(rng: &mut ChaCha8Rng, base: DVec3, amount: f64) -> DVec3 {
    (base
        + DVec3::new(
            rng.random_range(-amount..amount),
            rng.random_range(-amount..amount),
            rng.random_range(-amount..amount),
        ))
    .clamp(DVec3::splat(0.02), DVec3::splat(0.9))
}

impl Palette {
    /// A palette drawn from `rng`: sunny or hazy light, varied wall and paint colours.
    pub fn new(rng: &mut ChaCha8Rng) -> Self {
        let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
        let elevation = rng.random_range(20.0f64..55.0).to_radians();
        let sun_dir = DVec3::new(
            azimuth.cos() * elevation.cos(),
            azimuth.sin() * elevation.cos(),
            elevation.sin(),
        );
        let overcast = rng.random_bool(0.25);
        let sun_strength = if overcast {
            rng.random_range(0.25..0.4)
        } else {
            rng.random_range(0.75..0.95)
        };
        let sun = DVec3::new(1.0, 0.95, 0.86) * sun_strength;
        let ambient = DVec3::new(0.42, 0.45, 0.5) * rng.random_range(0.8..1.1)
            + DVec3::splat(if overcast { 0.25 } else { 0.0 });
        let zenith = if overcast {
            DVec3::splat(rng.random_range(0.6..0.75))
        } else {
            jitter(rng, DVec3::new(0.28, 0.45, 0.78), 0.06)
        };
        let horizon = if overcast {
            DVec3::splat(rng.random_range(0.75..0.88))
        } else {
            jitter(rng, DVec3::new(0.72, 0.8, 0.88), 0.04)
        };
        let wall_bases = [
            DVec3::new(0.75, 0.68, 0.55),
            DVec3::new(0.62, 0.35, 0.28),
            DVec3::new(0.8, 0.78, 0.72),
            DVec3::new(0.55, 0.58, 0.6),
            DVec3::new(0.78, 0.62, 0.4),
            DVec3::new(0.45, 0.5, 0.42),
        ];
        let walls = (0..5)
            .map(|_| {
                let base = wall_bases[rng.random_range(0..wall_bases.len())];
                jitter(rng, base, 0.07)
            })
            .collect();
        let paint_bases = [
            DVec3::new(0.8, 0.8, 0.82),
            DVec3::new(0.08, 0.08, 0.09),
            DVec3::new(0.55, 0.08, 0.07),
            DVec3::new(0.1, 0.2, 0.5),
            DVec3::new(0.45, 0.47, 0.5),
            DVec3::new(0.7, 0.6, 0.2),
        ];
        let paints = paint_bases.iter().map(|&b| jitter(rng, b, 0.05)).collect();
        Self {
            sun_dir,
            sun,
            ambient,
            zenith,
            horizon,
            haze: rng.random_range(250.0..600.0),
            asphalt: DVec3::splat(rng.random_range(0.2..0.32)),
            paving: jitter(rng, DVec3::new(0.55, 0.52, 0.48), 0.05),
            verge: jitter(rng, DVec3::new(0.3, 0.38, 0.18), 0.05),
            walls,
            paints,
            seed: rng.random(),
            ground_photos: [None; 3],
        }
    }

    /// Widens this palette for domain randomisation: any sun height, colour and strength
    /// (down to none), any ambient level, any haze; walls, paints and ground of any hue with
    /// the ranges' colour probability; photo textures on the ground with their photo
    /// probability.
    pub fn randomise(&mut self, rng: &mut ChaCha8Rng, ranges: &Randomisation) {
        let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
        let elevation = rng.random_range(5.0f64..75.0).to_radians();
        self.sun_dir = DVec3::new(
            azimuth.cos() * elevation.cos(),
            azimuth.sin() * elevation.cos(),
            elevation.sin(),
        );
        let warmth = rng.random_range(-0.25..0.25);
        self.sun = DVec3::new(1.0 + warmth, 0.97, 1.0 - warmth) * rng.random_range(0.0..1.1);
        self.ambient = DVec3::new(
            rng.random_range(0.3..0.6),
            rng.random_range(0.3..0.6),
            rng.random_range(0.3..0.6),
        ) * rng.random_range(0.5..1.6);
        self.haze = rng.random_range(80.0..800.0);
        let any = |rng: &mut ChaCha8Rng| {
            DVec3::new(
                rng.random_range(0.03..0.9),
                rng.random_range(0.03..0.9),
                rng.random_range(0.03..0.9),
            )
        };
        if rng.random_bool(ranges.colour_probability.clamp(0.0, 1.0)) {
            self.walls = (0..6).map(|_| any(rng)).collect();
            self.paints = (0..6).map(|_| any(rng)).collect();
            self.asphalt = any(rng) * 0.5;
            self.paving = any(rng);
            self.verge = any(rng);
        }
        for slot in &mut self.ground_photos {
            *slot = rng
                .random_bool(ranges.photo_probability.clamp(0.0, 1.0))
                .then(|| PhotoSurface::draw(rng, ranges.photo_period_m));
        }
    }

    /// Sky colour along a direction: horizon-to-zenith gradient with a glow around the sun.
    pub fn sky(&self, dir: DVec3) -> DVec3 {
        let d = dir.normalize();
        let up = d.z.max(0.0).sqrt();
        let glow = d.dot(self.sun_dir).max(0.0).powi(64) * 0.35;
        (self.horizon.lerp(self.zenith, up) + self.sun * glow).min(DVec3::splat(0.97))
    }

    /// Lambert shading with ambient light and the sun (visibility `lit` in [0, 1]), then
    /// haze towards the horizon colour over distance `dist`.
    pub fn shade(&self, albedo: DVec3, normal: DVec3, lit: f64, dist: f64) -> DVec3 {
        let cosine = normal.dot(self.sun_dir).max(0.0);
        let sky_light = self.ambient * (0.75 + 0.25 * normal.z);
        let colour = albedo * (sky_light + self.sun * (cosine * lit));
        let keep = (-dist / self.haze).exp();
        self.horizon.lerp(colour, keep)
    }

    /// Albedo and class of the ground at road coordinates (arc length `s`, `lateral`), for a
    /// filter footprint `w` metres.
    pub fn ground(&self, s: f64, lateral: f64, w: f64, world: DVec2) -> (DVec3, SurfaceClass) {
        let side = lateral.abs();
        let grain = fbm(self.seed, world.x, world.y, 2.0, 5, w);
        if side < ROAD_HALF {
            let centre = band(lateral, -0.075, 0.075, w) * stripes(s / 9.0, 3.0 / 9.0, w / 9.0);
            let edge = band(side, 3.5, 3.62, w);
            let mark = (centre + edge).min(1.0);
            let asphalt = self.ground_photos[0].map_or(self.asphalt * (1.0 + 0.35 * grain), |p| {
                p.albedo(s, lateral, w)
            });
            let albedo = asphalt.lerp(DVec3::new(0.85, 0.85, 0.8), mark);
            let class = if mark > 0.5 {
                SurfaceClass::Marking
            } else {
                SurfaceClass::Road
            };
            (albedo, class)
        } else if side < ROAD_HALF + KERB {
            (DVec3::splat(0.62) * (1.0 + 0.2 * grain), SurfaceClass::Kerb)
        } else if side < ROAD_HALF + KERB + SIDEWALK {
            let joints = stripes(s / 0.6, 0.06, w / 0.6).max(stripes(lateral / 0.6, 0.06, w / 0.6));
            let paving = self.ground_photos[1].map_or(self.paving * (1.0 + 0.25 * grain), |p| {
                p.albedo(s, lateral, w)
            });
            let albedo = paving * (1.0 - 0.35 * joints);
            (albedo, SurfaceClass::Sidewalk)
        } else {
            let verge = self.ground_photos[2].map_or(self.verge * (1.0 + 0.6 * grain), |p| {
                p.albedo(s, lateral, w)
            });
            (verge, SurfaceClass::Verge)
        }
    }
}

/// Albedo and class of a material at shape-local point `local`, with `horizontal_u` the
/// texture coordinate running around the shape, `normal_z` the world normal's z (upward
/// faces have it near 1, downward ones near -1), for a filter footprint `w` metres.
pub fn material_albedo(
    material: &Material,
    local: DVec3,
    horizontal_u: f64,
    normal_z: f64,
    w: f64,
) -> (DVec3, SurfaceClass) {
    let top = normal_z > 0.5;
    match *material {
        Material::Facade(style) => facade(&style, horizontal_u, local.z, top, w),
        Material::CarBody(paint) => {
            let sill = band(local.z, 0.0, 0.25, w);
            (paint.lerp(DVec3::splat(0.05), sill), SurfaceClass::Car)
        }
        Material::CarCabin(paint) => {
            let glass = if top {
                0.0
            } else {
                band(local.z, 0.05, 0.5, w)
            };
            (
                paint.lerp(DVec3::new(0.06, 0.07, 0.09), glass),
                SurfaceClass::Car,
            )
        }
        Material::Pole => (DVec3::splat(0.4), SurfaceClass::Pole),
        Material::Trunk => (
            DVec3::new(0.28, 0.2, 0.14)
                * (1.0 + 0.4 * fbm(7, horizontal_u, local.z * 0.3, 0.3, 3, w)),
            SurfaceClass::Trunk,
        ),
        Material::Canopy(tint) => {
            // Two projections of 2D noise, so no direction is left without variation.
            let leaves = fbm(11, local.x, local.z, 0.7, 4, w)
                + fbm(12, local.y, local.z + local.x, 0.7, 4, w);
            (tint * (1.0 + 1.2 * leaves), SurfaceClass::Canopy)
        }
        Material::Photo(photo) => {
            let albedo = match top {
                true => photo.albedo(local.x, local.y, w),
                false => photo.albedo(horizontal_u, local.z, w),
            };
            (albedo, SurfaceClass::Floater)
        }
        Material::Finish(finish) => {
            let albedo = match normal_z.abs() > 0.5 {
                true => finish.albedo(local.x, local.y, w),
                false => finish.albedo(horizontal_u, local.z, w),
            };
            (albedo, finish.class)
        }
    }
}

fn facade(style: &FacadeStyle, u: f64, z: f64, top: bool, w: f64) -> (DVec3, SurfaceClass) {
    let noise = fbm(style.seed, u, z, 1.5, 4, w);
    if let Some(photo) = style.photo {
        return facade_windows(style, photo.albedo(u, z, w), u, z, top, w);
    }
    if style.plain {
        return (style.wall * (1.0 + 0.04 * noise), SurfaceClass::PlainWall);
    }
    facade_windows(style, style.wall * (1.0 + 0.15 * noise), u, z, top, w)
}

/// A facade's plinth, cornices and window grid over the wall albedo `wall`.
fn facade_windows(
    style: &FacadeStyle,
    mut wall: DVec3,
    u: f64,
    z: f64,
    top: bool,
    w: f64,
) -> (DVec3, SurfaceClass) {
    let plinth = band(z, -1.0, 0.6, w);
    wall = wall.lerp(wall * 0.55, plinth);
    let cornice = stripes(z / style.storey - 0.02, 0.05, w / style.storey);
    wall = wall.lerp(wall * 0.8, cornice);
    if top {
        return (wall * 0.7, SurfaceClass::Facade);
    }
    let columns = stripes(
        u / style.column - 0.5 * (1.0 - style.window_duty),
        style.window_duty,
        w / style.column,
    );
    let rows = if z > style.storey {
        stripes(z / style.storey - 0.3, 0.5, w / style.storey)
    } else {
        // Ground floor: tall shop windows.
        band(z, 0.8, 2.6, w)
    };
    let window = columns * rows;
    let glass = style.glass * (0.8 + 0.4 * (z / 20.0).fract());
    let class = if window > 0.5 {
        SurfaceClass::Window
    } else {
        SurfaceClass::Facade
    };
    (wall.lerp(glass, window), class)
}
