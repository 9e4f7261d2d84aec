//! Analytic ray intersection with the scene's shapes: yawed boxes, vertical cylinders,
//! vertical-axis ellipsoids and the ground plane z = 0. Rays carry unnormalised directions,
//! so a camera ray built as `R (x, y, 1)` returns its z-depth as the hit parameter.

use glam::DVec3;

/// A ray `origin + t * dir`; `dir` need not be unit length.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Start point, world coordinates (z up).
    pub origin: DVec3,
    /// Direction, any positive length.
    pub dir: DVec3,
}

impl Ray {
    /// The point at parameter `t`.
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + self.dir * t
    }
}

/// Smallest hit parameter accepted (avoids self-intersection of secondary rays).
pub const T_MIN: f64 = 1e-7;

/// A ray hit on a shape: parameter, outward unit normal and the point in shape-local
/// coordinates (for texturing: x along the shape's length, y across, z up from its base).
#[derive(Clone, Copy, Debug)]
pub struct ShapeHit {
    /// Ray parameter.
    pub t: f64,
    /// Outward unit normal, world.
    pub normal: DVec3,
    /// Hit point in the shape's local frame.
    pub local: DVec3,
}

/// An analytic solid.
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    /// A box standing on its base, rotated by `yaw` about z; `centre` is the centre of its
    /// base face's footprint at height `centre.z` of the base, `half` the half extents
    /// (x along the yaw direction, y across, z = half the height).
    Box {
        /// Centre of the bottom face.
        centre: DVec3,
        /// (cos yaw, sin yaw).
        axis: (f64, f64),
        /// Half extents.
        half: DVec3,
    },
    /// A vertical cylinder with a flat top.
    Cylinder {
        /// Centre of the bottom disc.
        base: DVec3,
        /// Radius.
        radius: f64,
        /// Height.
        height: f64,
    },
    /// An ellipsoid with vertical and horizontal principal axes.
    Ellipsoid {
        /// Centre.
        centre: DVec3,
        /// Radii along x, y, z.
        radii: DVec3,
    },
}

impl Shape {
    /// A bounding sphere (centre, radius).
    pub fn bounds(&self) -> (DVec3, f64) {
        match *self {
            Shape::Box { centre, half, .. } => (centre + DVec3::Z * half.z, half.length()),
            Shape::Cylinder {
                base,
                radius,
                height,
            } => (
                base + DVec3::Z * (0.5 * height),
                (radius * radius + 0.25 * height * height).sqrt(),
            ),
            Shape::Ellipsoid { centre, radii } => (centre, radii.max_element()),
        }
    }

    /// The nearest hit with `T_MIN < t < t_max`, if any.
    pub fn intersect(&self, ray: &Ray, t_max: f64) -> Option<ShapeHit> {
        match *self {
            Shape::Box { centre, axis, half } => box_hit(ray, centre, axis, half, t_max),
            Shape::Cylinder {
                base,
                radius,
                height,
            } => cylinder_hit(ray, base, radius, height, t_max),
            Shape::Ellipsoid { centre, radii } => ellipsoid_hit(ray, centre, radii, t_max),
        }
    }
}

fn to_local(v: DVec3, (c, s): (f64, f64)) -> DVec3 {
    DVec3::new(c * v.x + s * v.y, -s * v.x + c * v.y, v.z)
}

fn to_world(v: DVec3, (c, s): (f64, f64)) -> DVec3 {
    DVec3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
}

fn box_hit(
    ray: &Ray,
    centre: DVec3,
    axis: (f64, f64),
    half: DVec3,
    t_max: f64,
) -> Option<ShapeHit> {
    let mid = DVec3::new(0.0, 0.0, half.z);
    let o = to_local(ray.origin - centre, axis) - mid;
    let d = to_local(ray.dir, axis);
    let mut t_near = f64::NEG_INFINITY;
    let mut t_far = f64::INFINITY;
    let mut near_axis = 0;
    for k in 0..3 {
        let (ok, dk, hk) = (o[k], d[k], half[k]);
        if dk.abs() < 1e-300 {
            if ok.abs() > hk {
                return None;
            }
            continue;
        }
        let inv = 1.0 / dk;
        let (mut t0, mut t1) = ((-hk - ok) * inv, (hk - ok) * inv);
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        if t0 > t_near {
            t_near = t0;
            near_axis = k;
        }
        t_far = t_far.min(t1);
    }
    if t_near > t_far || t_near <= T_MIN || t_near >= t_max {
        return None;
    }
    let mut n = DVec3::ZERO;
    n[near_axis] = -d[near_axis].signum();
    let local = o + d * t_near + mid;
    Some(ShapeHit {
        t: t_near,
        normal: to_world(n, axis),
        local,
    })
}

fn cylinder_hit(ray: &Ray, base: DVec3, radius: f64, height: f64, t_max: f64) -> Option<ShapeHit> {
    let o = ray.origin - base;
    let d = ray.dir;
    let mut best: Option<ShapeHit> = None;
    let a = d.x * d.x + d.y * d.y;
    if a > 1e-300 {
        let b = o.x * d.x + o.y * d.y;
        let c = o.x * o.x + o.y * o.y - radius * radius;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let t = (-b - disc.sqrt()) / a;
            let z = o.z + t * d.z;
            if t > T_MIN && t < t_max && (0.0..=height).contains(&z) {
                let p = o + d * t;
                best = Some(ShapeHit {
                    t,
                    normal: DVec3::new(p.x, p.y, 0.0) / radius,
                    local: p,
                });
            }
        }
    }
    if d.z < 0.0 {
        let t = (height - o.z) / d.z;
        let p = o + d * t;
        let limit = best.map_or(t_max, |h| h.t);
        if t > T_MIN && t < limit && p.x * p.x + p.y * p.y <= radius * radius {
            best = Some(ShapeHit {
                t,
                normal: DVec3::Z,
                local: p,
            });
        }
    }
    best
}

fn ellipsoid_hit(ray: &Ray, centre: DVec3, radii: DVec3, t_max: f64) -> Option<ShapeHit> {
    let o = (ray.origin - centre) / radii;
    let d = ray.dir / radii;
    let a = d.dot(d);
    let b = o.dot(d);
    let c = o.dot(o) - 1.0;
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / a;
    if t <= T_MIN || t >= t_max {
        return None;
    }
    let unit = o + d * t;
    Some(ShapeHit {
        t,
        normal: (unit / radii).normalize(),
        local: unit * radii,
    })
}

/// The horizontal plane at `height` seen from above: the hit parameter, if the ray goes down.
pub fn plane_hit(ray: &Ray, height: f64) -> Option<f64> {
    if ray.dir.z < 0.0 && ray.origin.z > height {
        Some((height - ray.origin.z) / ray.dir.z)
    } else {
        None
    }
}

/// Whether the ray can hit a sphere before `t_max` (a cheap pre-test).
pub fn may_hit_sphere(ray: &Ray, centre: DVec3, radius: f64, t_max: f64) -> bool {
    let oc = centre - ray.origin;
    let dd = ray.dir.dot(ray.dir);
    let tc = oc.dot(ray.dir) / dd;
    let dist2 = oc.dot(oc) - tc * tc * dd;
    if dist2 > radius * radius {
        return false;
    }
    let half = ((radius * radius - dist2) / dd).sqrt();
    tc + half > T_MIN && tc - half < t_max
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_hit_where_expected() {
        let ray = Ray {
            origin: DVec3::new(-10.0, 0.0, 1.0),
            dir: DVec3::X,
        };
        let b = Shape::Box {
            centre: DVec3::ZERO,
            axis: (1.0, 0.0),
            half: DVec3::new(2.0, 1.0, 1.5),
        };
        let h = b.intersect(&ray, 100.0).unwrap();
        assert!((h.t - 8.0).abs() < 1e-12 && h.normal.x == -1.0);
        let c = Shape::Cylinder {
            base: DVec3::ZERO,
            radius: 0.5,
            height: 3.0,
        };
        assert!((c.intersect(&ray, 100.0).unwrap().t - 9.5).abs() < 1e-12);
        let e = Shape::Ellipsoid {
            centre: DVec3::new(0.0, 0.0, 1.0),
            radii: DVec3::new(2.0, 2.0, 1.0),
        };
        assert!((e.intersect(&ray, 100.0).unwrap().t - 8.0).abs() < 1e-12);
        assert!(e.intersect(&ray, 7.0).is_none());
    }
}
