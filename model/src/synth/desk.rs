//! The desk: a table top 0.2-1 m below and ahead of a handheld (or arm-mounted) camera that
//! looks down at it, with objects on it (boxes, cans, balls and hands), a backdrop wall
//! 1-3 m away, in a small room. The scale users' desks and robot arms see: 100-200 px of
//! disparity for a 10 cm rig at 640 px.

use std::f64::consts::FRAC_PI_2;

use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use renderer::Intrinsics;

use super::config::SynthConfig;
use super::indoor::{
    block, enclosure, jitter, wall_panels, Extent, Finishes, HandheldPath, IndoorScene, PathRanges,
};
use super::primitives::Shape;
use super::randomise::range;
use super::scene::Object;
use super::shading::{Finish, Material, SurfaceClass};

/// Height of the table top above the floor, metres.
pub const TABLE_HEIGHT: f64 = 0.75;

/// The distance range (metres, along the optical axis to the table top) a desk draws from.
pub const VIEW_DISTANCE_M: (f64, f64) = (0.3, 0.6);

/// The camera's half vertical field of view, radians.
fn half_vfov(k: &Intrinsics) -> f64 {
    (0.5 * k.height as f64 / k.fy as f64).atan()
}

/// Builds the desk of `config` seen through intrinsics `k`, from `rng`.
pub fn build(rng: &mut ChaCha8Rng, config: &SynthConfig, k: &Intrinsics) -> IndoorScene {
    let randomise = config.randomise.as_ref();
    let finishes = Finishes::new(rng, randomise);
    let half_v = half_vfov(k);
    let half_h = (0.5 * k.width as f64 / k.fx as f64).atan();
    // Look down steeply enough that the table fills most of the view.
    let pitch = (half_v + range(rng, (5f64.to_radians(), 22f64.to_radians())))
        .clamp(30f64.to_radians(), 75f64.to_radians());
    let distance = config
        .view_distance_m
        .unwrap_or_else(|| range(rng, VIEW_DISTANCE_M));
    let lift = distance * pitch.sin();
    let camera = DVec3::new(0.0, 0.0, TABLE_HEIGHT + lift);
    // Sweeping sideways over the table (10 cm bins always close), nodding a little.
    let drift = DVec3::new(
        range(rng, (0.08, 0.2)),
        range(rng, (0.02, 0.06)),
        range(rng, (0.01, 0.03)),
    );
    let path = HandheldPath::new(
        rng,
        &PathRanges {
            centre: camera,
            heading_pitch: (FRAC_PI_2, pitch),
            amplitude: drift,
            speed: (0.008, 0.025),
            wobble: 3f64.to_radians(),
        },
    );

    // Where the top image row meets the table plane (or far, if above the horizon).
    let top_ray = pitch - half_v;
    let reach = match top_ray > 0.05 {
        true => (lift / top_ray.tan()).min(2.5),
        false => 2.5,
    };
    let backdrop = (reach + range(rng, (0.1, 0.5))).clamp(1.0, 3.0);
    let table_front = -range(rng, (0.15, 0.35));
    let table_back = (reach + range(rng, (-0.2, 0.3))).clamp(0.4, backdrop - 0.05);
    let table_half = ((reach + 0.3) * half_h.tan() + drift.x + 0.1).clamp(0.5, 1.8);
    let extent = Extent {
        half_width: table_half + range(rng, (0.3, 1.5)),
        back: table_front - range(rng, (0.5, 1.5)),
        front: backdrop,
        height: range(rng, (2.4, 3.0)),
    };
    let mut objects = enclosure(rng, &finishes, &extent);
    let panels = rng.random_range(0..3);
    objects.extend(wall_panels(rng, &finishes, &extent, panels));

    let wood = [
        DVec3::new(0.55, 0.38, 0.22),
        DVec3::new(0.75, 0.62, 0.45),
        DVec3::new(0.7, 0.7, 0.68),
        DVec3::new(0.2, 0.2, 0.22),
    ][rng.random_range(0..4)];
    let top = finishes.draw(rng, SurfaceClass::Table, wood, 0.08, (0.15, 0.8));
    let thickness = 0.03;
    let table = block(
        DVec3::new(
            0.0,
            0.5 * (table_front + table_back),
            TABLE_HEIGHT - thickness,
        ),
        DVec3::new(
            table_half,
            0.5 * (table_back - table_front),
            0.5 * thickness,
        ),
        0.0,
    );
    objects.push(Object::new(table, Material::Finish(top)));
    for (sx, y) in [
        (-1.0, table_front),
        (1.0, table_front),
        (-1.0, table_back),
        (1.0, table_back),
    ] {
        let leg = Shape::Cylinder {
            base: DVec3::new(
                sx * (table_half - 0.05),
                y + 0.05 * (table_front - y).signum(),
                0.0,
            ),
            radius: 0.025,
            height: TABLE_HEIGHT - thickness,
        };
        objects.push(Object::new(leg, Material::Finish(top)));
    }

    // Objects on the table where the camera sees them, never within 12 cm of its height.
    let tallest = (lift - 0.12).clamp(0.02, 0.25);
    // The nearest table point in view (under the bottom image row), and how far sideways
    // the view reaches at a distance.
    let bottom_ray = (pitch + half_v).min(1.5);
    let area = Area {
        x: table_half - 0.08,
        y: (
            (lift / bottom_ray.tan()).max(table_front + 0.08),
            (table_back - 0.05).min(0.8 * reach),
        ),
        lift,
        tan_half_h: half_h.tan(),
    };
    let items = rng.random_range(6..16);
    // An object's top stays at least 0.2 m from the camera: tall ones stand farther away.
    let tallest_at = |at: DVec3| (0.5 * (at.y.hypot(lift) - 0.2)).clamp(0.02, tallest);
    for _ in 0..items {
        let at = area.draw(rng);
        objects.push(item(rng, &finishes, at, tallest_at(at)));
    }
    for _ in 0..rng.random_range(0..3) {
        let at = area.draw(rng);
        hand(rng, at, tallest_at(at), &mut objects);
    }
    IndoorScene { objects, path }
}

/// The part of the table top the camera sees: a y range ahead of it and, at each y, the
/// width the field of view spans there (within the table's half width `x`).
struct Area {
    x: f64,
    y: (f64, f64),
    lift: f64,
    tan_half_h: f64,
}

impl Area {
    fn draw(&self, rng: &mut ChaCha8Rng) -> DVec3 {
        // Nearer rows of the table cover more of the image: draw them more often.
        let u = rng.random_range(0.0..1.0f64);
        let y = self.y.0 + (self.y.1 - self.y.0).max(0.0) * u * u;
        let half = (y.hypot(self.lift) * self.tan_half_h).min(self.x);
        DVec3::new(range(rng, (-half, half)), y, TABLE_HEIGHT)
    }
}

/// One object standing on the table at `at`: a yawed box (a book, a carton), a can or mug,
/// or a ball, at most `tallest` metres high.
fn item(rng: &mut ChaCha8Rng, finishes: &Finishes, at: DVec3, tallest: f64) -> Object {
    let colour = DVec3::new(
        rng.random_range(0.1..0.9),
        rng.random_range(0.1..0.9),
        rng.random_range(0.1..0.9),
    );
    let finish = finishes.draw(rng, SurfaceClass::Item, colour, 0.03, (0.05, 0.3));
    let shape = match rng.random_range(0..3) {
        0 => block(
            at,
            DVec3::new(
                rng.random_range(0.02..0.12),
                rng.random_range(0.02..0.1),
                0.5 * rng.random_range(0.01..tallest.max(0.011)),
            ),
            rng.random_range(0.0..std::f64::consts::PI),
        ),
        1 => Shape::Cylinder {
            base: at,
            radius: rng.random_range(0.02..0.05),
            height: rng.random_range(0.03..tallest.max(0.031)),
        },
        _ => {
            let r = rng.random_range(0.015..0.06f64).min(0.5 * tallest);
            Shape::Ellipsoid {
                centre: at + DVec3::Z * r,
                radii: DVec3::splat(r),
            }
        }
    };
    Object::new(shape, Material::Finish(finish))
}

/// A hand at `at` (palm centre on the table, or hovering over it as if reaching): a palm,
/// four fingers and a thumb along one table axis, and a forearm leading away from it.
fn hand(rng: &mut ChaCha8Rng, at: DVec3, tallest: f64, out: &mut Vec<Object>) {
    let skins = [
        DVec3::new(0.87, 0.68, 0.57),
        DVec3::new(0.72, 0.52, 0.4),
        DVec3::new(0.5, 0.34, 0.24),
        DVec3::new(0.3, 0.2, 0.15),
    ];
    let skin = Finish {
        class: SurfaceClass::Hand,
        base: {
            let tone = skins[rng.random_range(0..skins.len())];
            jitter(rng, tone, 0.04)
        },
        grain: rng.random_range(0.1..0.25),
        cell: 0.01,
        seed: rng.random(),
        photo: None,
    };
    let scale = rng.random_range(0.85..1.15);
    let hover = match rng.random_bool(0.4) {
        true => range(rng, (0.0, tallest - 0.03)),
        false => 0.0,
    };
    // Along x or y, pointing either way: `a` along the fingers, `b` across the palm.
    let (a, b) = match rng.random_range(0..4) {
        0 => (DVec3::X, DVec3::Y),
        1 => (-DVec3::X, DVec3::Y),
        2 => (DVec3::Y, DVec3::X),
        _ => (-DVec3::Y, DVec3::X),
    };
    let radii = |along: f64, across: f64, up: f64| (a * along + b * across).abs() + DVec3::Z * up;
    let palm_r = radii(0.045, 0.04, 0.014) * scale;
    let centre = at + DVec3::Z * (palm_r.z + hover);
    let mut parts = vec![(centre, palm_r)];
    for (k, length) in [0.038, 0.045, 0.043, 0.034].into_iter().enumerate() {
        let length = length * scale * rng.random_range(0.9..1.1);
        let across = (k as f64 - 1.5) * 0.02 * scale;
        let base = centre + a * (0.04 * scale + length) + b * across;
        parts.push((base, radii(length, 0.009 * scale, 0.009 * scale)));
    }
    let thumb = centre + b * (0.05 * scale) + a * (0.01 * scale);
    parts.push((thumb, radii(0.012 * scale, 0.03 * scale, 0.01 * scale)));
    let forearm = centre - a * (0.16 * scale);
    parts.push((forearm, radii(0.13 * scale, 0.032 * scale, 0.028 * scale)));
    for (centre, radii) in parts {
        let shape = Shape::Ellipsoid { centre, radii };
        out.push(Object::new(shape, Material::Finish(skin)));
    }
}
