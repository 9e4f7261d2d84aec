//! Ray casting through one frame's world: nearest hit among the ground and the nearby
//! objects (objects pre-sorted by distance from the shared ray origin so a ray stops testing
//! once no remaining object can be nearer than its current hit), sun shadows and shading.

use glam::{DVec2, DVec3};

use super::primitives::{may_hit_sphere, plane_hit, Ray, Shape};
use super::scene::Object;
use super::shading::{material_albedo, Palette, SurfaceClass, KERB, ROAD_HALF};
use super::trajectory::Road;

/// How far the ground reaches, metres: beyond it a ray sees sky, so depth stays bounded
/// (the band it removes is far thinner than a pixel at the horizon).
const GROUND_EXTENT: f64 = 1000.0;

/// Height of the kerb: sidewalks and verges lie this much above the road, metres.
pub const KERB_HEIGHT: f64 = 0.12;

/// Where a ray meets the ground (road, kerb face or raised sidewalk level).
#[derive(Clone, Copy, Debug)]
struct GroundHit {
    t: f64,
    normal: DVec3,
    /// Road coordinates (arc length, lateral) of the hit.
    road: (f64, f64),
}

/// A surface point a ray found.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    /// Ray parameter (z-depth for camera rays built with unit camera z).
    pub t: f64,
    /// World position.
    pub point: DVec3,
    /// Outward unit normal.
    pub normal: DVec3,
    /// Albedo (filtered for the ray's footprint).
    pub albedo: DVec3,
    /// Semantic class.
    pub class: SurfaceClass,
}

/// One frame's world: road, palette and the objects near the vehicle.
pub struct World<'a> {
    /// The street's road (its ground); `None` indoors, where every surface is an object.
    road: Option<&'a Road>,
    palette: &'a Palette,
    objects: Vec<Object>,
    arc: f64,
    anchor: DVec3,
    tangent: DVec2,
    /// Objects sorted by `along` of their bounding-sphere centre (for shadow-ray culling).
    by_along: Vec<(f64, u32)>,
    /// Largest bounding radius.
    max_radius: f64,
    /// Highest point of any object that casts a shadow.
    top: f64,
}

/// Objects ordered by the distance from one ray origin to their bounding spheres.
pub struct Ordering {
    origin: DVec3,
    near: Vec<(f64, u32)>,
}

impl<'a> World<'a> {
    /// The world around arc length `arc` (vehicle at `anchor`) with the given objects.
    pub fn new(
        road: &'a Road,
        palette: &'a Palette,
        objects: Vec<Object>,
        arc: f64,
        anchor: DVec3,
    ) -> Self {
        Self::build(Some(road), palette, objects, arc, anchor, road.tangent(arc))
    }

    /// A world without a road: only `objects` (an enclosure and what it holds), with
    /// shadow culling along the horizontal unit direction `tangent` from `anchor`.
    pub fn indoor(
        palette: &'a Palette,
        objects: Vec<Object>,
        anchor: DVec3,
        tangent: DVec2,
    ) -> Self {
        Self::build(None, palette, objects, 0.0, anchor, tangent)
    }

    fn build(
        road: Option<&'a Road>,
        palette: &'a Palette,
        objects: Vec<Object>,
        arc: f64,
        anchor: DVec3,
        tangent: DVec2,
    ) -> Self {
        let along = |p: DVec3| (p - anchor).truncate().dot(tangent);
        let mut by_along: Vec<(f64, u32)> = objects
            .iter()
            .enumerate()
            .map(|(i, o)| (along(o.centre), i as u32))
            .collect();
        by_along.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let max_radius = objects.iter().map(|o| o.radius).fold(0.0, f64::max);
        let top = objects
            .iter()
            .filter(|o| o.casts_shadow)
            .map(|o| o.centre.z + o.radius)
            .fold(0.0, f64::max);
        Self {
            road,
            palette,
            objects,
            arc,
            anchor,
            tangent,
            by_along,
            max_radius,
            top,
        }
    }

    /// Distance of a point's ground projection along the road tangent at the anchor: never
    /// more than the distance between two points, so intervals of it cull objects exactly.
    fn along(&self, p: DVec3) -> f64 {
        (p - self.anchor).truncate().dot(self.tangent)
    }

    /// Objects sorted for rays leaving `origin` (ties broken by index: deterministic).
    pub fn ordering(&self, origin: DVec3) -> Ordering {
        let mut near: Vec<(f64, u32)> = self
            .objects
            .iter()
            .enumerate()
            .map(|(i, o)| ((o.centre - origin).length() - o.radius, i as u32))
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        Ordering { origin, near }
    }

    /// The nearest surface along `ray` (which must start at `order`'s origin) before
    /// `t_max`; `pixel_angle` is the angular size of the ray's footprint (radians) for
    /// texture filtering.
    pub fn cast(
        &self,
        order: &Ordering,
        ray: &Ray,
        t_max: f64,
        pixel_angle: f64,
    ) -> Option<Surface> {
        debug_assert!(order.origin == ray.origin);
        let dir_len = ray.dir.length();
        let ground_limit = t_max.min(GROUND_EXTENT / dir_len);
        let ground = self.ground(ray).filter(|g| g.t < ground_limit);
        let mut best_t = ground.map_or(t_max, |g| g.t);
        let mut best = None;
        for &(near, i) in &order.near {
            if near > best_t * dir_len {
                break;
            }
            let object = &self.objects[i as usize];
            if !may_hit_sphere(ray, object.centre, object.radius, best_t) {
                continue;
            }
            if let Some(hit) = object.shape.intersect(ray, best_t) {
                best_t = hit.t;
                best = Some((i, hit));
            }
        }
        let dist = best_t * dir_len;
        let unit = ray.dir / dir_len;
        if let Some((i, hit)) = best {
            let object = &self.objects[i as usize];
            let cosine = hit.normal.dot(unit).abs().max(0.15);
            let w = dist * pixel_angle / cosine;
            let u = match object.shape {
                Shape::Cylinder { radius, .. } => hit.local.y.atan2(hit.local.x) * radius,
                _ => hit.local.x + hit.local.y,
            };
            let (albedo, class) = material_albedo(&object.material, hit.local, u, hit.normal.z, w);
            return Some(Surface {
                t: hit.t,
                point: ray.at(hit.t),
                normal: hit.normal,
                albedo,
                class,
            });
        }
        let ground = ground?;
        let point = ray.at(ground.t);
        let cosine = ground.normal.dot(unit).abs().max(0.15);
        let w = dist * pixel_angle / cosine;
        let (s, lateral) = ground.road;
        let (albedo, class) = self.palette.ground(s, lateral, w, point.truncate());
        Some(Surface {
            t: ground.t,
            point,
            normal: ground.normal,
            albedo,
            class,
        })
    }

    /// Road coordinates of a ground point.
    fn road_coords(&self, road: &Road, p: DVec3) -> (f64, f64) {
        road.project(p.truncate(), self.arc + self.along(p))
    }

    /// The ground a ray meets first: the raised level (|lateral| >= ROAD_HALF) at kerb
    /// height, else the road at z = 0, else the kerb's vertical face between them (found by
    /// bisection on the lateral offset, which the ray crosses once between the two planes).
    fn ground(&self, ray: &Ray) -> Option<GroundHit> {
        let road = self.road?;
        let upper = plane_hit(ray, KERB_HEIGHT)?;
        let up = self.road_coords(road, ray.at(upper));
        if up.1.abs() >= ROAD_HALF {
            return Some(GroundHit {
                t: upper,
                normal: DVec3::Z,
                road: up,
            });
        }
        let lower = plane_hit(ray, 0.0)?;
        let low = self.road_coords(road, ray.at(lower));
        if low.1.abs() < ROAD_HALF {
            return Some(GroundHit {
                t: lower,
                normal: DVec3::Z,
                road: low,
            });
        }
        let side = low.1.signum();
        let (mut a, mut b) = (upper, lower);
        for _ in 0..40 {
            let mid = 0.5 * (a + b);
            if self.road_coords(road, ray.at(mid)).1.abs() < ROAD_HALF {
                a = mid;
            } else {
                b = mid;
            }
        }
        let (s, _) = self.road_coords(road, ray.at(b));
        let tangent = road.tangent(s);
        let towards_road = DVec2::new(tangent.y, -tangent.x) * side;
        Some(GroundHit {
            t: b,
            normal: towards_road.extend(0.0),
            road: (s, side * (ROAD_HALF + 0.5 * KERB)),
        })
    }

    /// Whether the sun is hidden from `point` (with outward `normal`) by an object. Only
    /// objects whose `along` interval meets the shadow ray's (up to where it rises above
    /// every object) are tested.
    fn shadowed(&self, point: DVec3, normal: DVec3) -> bool {
        let sun = self.palette.sun_dir;
        if normal.dot(sun) <= 0.0 || point.z >= self.top {
            return false;
        }
        let ray = Ray {
            origin: point + normal * 1e-4,
            dir: sun,
        };
        let reach = (self.top - point.z) / sun.z;
        let start = self.along(ray.origin);
        let end = start + reach * sun.truncate().dot(self.tangent);
        let lo = start.min(end) - self.max_radius;
        let hi = start.max(end) + self.max_radius;
        let first = self.by_along.partition_point(|&(a, _)| a < lo);
        self.by_along[first..]
            .iter()
            .take_while(|&&(a, _)| a <= hi)
            .any(|&(_, i)| {
                let o = &self.objects[i as usize];
                o.casts_shadow
                    && may_hit_sphere(&ray, o.centre, o.radius, reach)
                    && o.shape.intersect(&ray, reach).is_some()
            })
    }

    /// Colour seen along a ray: the shaded surface (with sun shadows and haze) or the sky.
    /// Also returns the surface found, if any.
    pub fn radiance(
        &self,
        order: &Ordering,
        ray: &Ray,
        pixel_angle: f64,
    ) -> (DVec3, Option<Surface>) {
        match self.cast(order, ray, f64::INFINITY, pixel_angle) {
            Some(surface) => {
                let lit = if self.shadowed(surface.point, surface.normal) {
                    0.0
                } else {
                    1.0
                };
                let dist = surface.t * ray.dir.length();
                let colour = self
                    .palette
                    .shade(surface.albedo, surface.normal, lit, dist);
                (colour, Some(surface))
            }
            None => (self.palette.sky(ray.dir), None),
        }
    }
}
