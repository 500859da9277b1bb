//! Exact ray-shape intersection in object space, the CPU twin of
//! shaders/lib/intersect.wgsl (same formulas, same order, so the two agree).
//!
//! Rays are (origin, dir) with dir NOT normalized: an instance's ray is the
//! world ray mapped by the inverse matrix, so t is the same in both spaces.
//! Each function returns the nearest t in (t_min, t_max) and the outward
//! object-space normal there (planes: +y).

use glam::{Vec2, Vec3};

use super::layout::{
    GpuTriangle, SHAPE_BOX, SHAPE_CONE, SHAPE_CYLINDER, SHAPE_DISK, SHAPE_QUAD, SHAPE_SPHERE,
};

/// A hit in object space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectHit {
    pub t: f32,
    pub normal: Vec3,
    /// Geometric normal, outward (for triangles: by counter-clockwise winding).
    pub geometric: Vec3,
}

fn hit(t: f32, n: Vec3) -> Option<ObjectHit> {
    Some(ObjectHit {
        t,
        normal: n,
        geometric: n,
    })
}

/// Picks the nearer of two roots inside (t_min, t_max).
fn pick(t0: f32, t1: f32, t_min: f32, t_max: f32) -> Option<f32> {
    if t0 > t_min && t0 < t_max {
        Some(t0)
    } else if t1 > t_min && t1 < t_max {
        Some(t1)
    } else {
        None
    }
}

/// Sphere of radius r at the origin: |o + t d|^2 = r^2.
pub fn sphere(o: Vec3, d: Vec3, r: f32, t_min: f32, t_max: f32) -> Option<ObjectHit> {
    let a = d.dot(d);
    let b = o.dot(d);
    let c = o.dot(o) - r * r;
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let t = pick((-b - s) / a, (-b + s) / a, t_min, t_max)?;
    hit(t, (o + d * t) / r)
}

/// Box of half extents h at the origin, by slabs.
pub fn aabox(o: Vec3, d: Vec3, h: Vec3, t_min: f32, t_max: f32) -> Option<ObjectHit> {
    let inv = d.recip();
    let t1 = (-h - o) * inv;
    let t2 = (h - o) * inv;
    let near = t1.min(t2).max_element();
    let far = t1.max(t2).min_element();
    if near > far {
        return None;
    }
    let t = pick(near, far, t_min, t_max)?;
    // The face is the axis where the hit point is closest to the box's side.
    let p = (o + d * t) / h;
    let a = p.abs();
    let n = if a.x >= a.y && a.x >= a.z {
        Vec3::new(p.x.signum(), 0.0, 0.0)
    } else if a.y >= a.z {
        Vec3::new(0.0, p.y.signum(), 0.0)
    } else {
        Vec3::new(0.0, 0.0, p.z.signum())
    };
    hit(t, n)
}

/// Capped cylinder of radius r around +y, from y = -height/2 to +height/2.
pub fn cylinder(
    o: Vec3,
    d: Vec3,
    r: f32,
    height: f32,
    t_min: f32,
    t_max: f32,
) -> Option<ObjectHit> {
    let half = height * 0.5;
    let mut best: Option<ObjectHit> = None;
    let mut t_far = t_max;
    // Side: x^2 + z^2 = r^2.
    let a = d.x * d.x + d.z * d.z;
    if a > 0.0 {
        let b = o.x * d.x + o.z * d.z;
        let c = o.x * o.x + o.z * o.z - r * r;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let s = disc.sqrt();
            for t in [(-b - s) / a, (-b + s) / a] {
                let y = o.y + d.y * t;
                if t > t_min && t < t_far && y.abs() <= half {
                    let p = o + d * t;
                    best = hit(t, Vec3::new(p.x, 0.0, p.z) / r);
                    t_far = t;
                    break;
                }
            }
        }
    }
    // Caps: y = +-half, inside the radius.
    if d.y != 0.0 {
        for cap in [half, -half] {
            let t = (cap - o.y) / d.y;
            let p = o + d * t;
            if t > t_min && t < t_far && p.x * p.x + p.z * p.z <= r * r {
                best = hit(t, Vec3::new(0.0, cap.signum(), 0.0));
                t_far = t;
            }
        }
    }
    best
}

/// Cone around +y: base disk of radius r at y = 0 (capped), apex at y = height.
pub fn cone(o: Vec3, d: Vec3, r: f32, height: f32, t_min: f32, t_max: f32) -> Option<ObjectHit> {
    let k = r / height;
    let k2 = k * k;
    let mut best: Option<ObjectHit> = None;
    let mut t_far = t_max;
    // Side: x^2 + z^2 = k^2 (height - y)^2, with 0 <= y <= height.
    let hy = height - o.y;
    let a = d.x * d.x + d.z * d.z - k2 * d.y * d.y;
    let b = o.x * d.x + o.z * d.z + k2 * hy * d.y;
    let c = o.x * o.x + o.z * o.z - k2 * hy * hy;
    let mut roots = [f32::NAN, f32::NAN];
    if a.abs() > 1e-12 {
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let s = disc.sqrt();
            let (r0, r1) = ((-b - s) / a, (-b + s) / a);
            roots = [r0.min(r1), r0.max(r1)];
        }
    } else if b.abs() > 1e-12 {
        roots = [-c / (2.0 * b), f32::NAN];
    }
    for t in roots {
        if t.is_nan() {
            continue;
        }
        let p = o + d * t;
        if t > t_min && t < t_far && p.y >= 0.0 && p.y <= height {
            best = hit(t, Vec3::new(p.x, k2 * (height - p.y), p.z).normalize());
            t_far = t;
            break;
        }
    }
    if d.y != 0.0 {
        let t = -o.y / d.y;
        let p = o + d * t;
        if t > t_min && t < t_far && p.x * p.x + p.z * p.z <= r * r {
            best = hit(t, Vec3::NEG_Y);
        }
    }
    best
}

/// The plane y = 0 inside |x| <= half.x, |z| <= half.y (quad) or inside
/// x^2 + z^2 <= radius^2 (disk, `half.x` = radius, `disk` = true).
pub fn plane(
    o: Vec3,
    d: Vec3,
    half: Vec2,
    disk: bool,
    t_min: f32,
    t_max: f32,
) -> Option<ObjectHit> {
    if d.y == 0.0 {
        return None;
    }
    let t = -o.y / d.y;
    if !(t > t_min && t < t_max) {
        return None;
    }
    let p = o + d * t;
    let inside = if disk {
        p.x * p.x + p.z * p.z <= half.x * half.x
    } else {
        p.x.abs() <= half.x && p.z.abs() <= half.y
    };
    if inside {
        hit(t, Vec3::Y)
    } else {
        None
    }
}

/// Moller-Trumbore; the shading normal interpolates the vertex normals by
/// the barycentric coordinates (as the rasterizer does).
pub fn triangle(o: Vec3, d: Vec3, tri: &GpuTriangle, t_min: f32, t_max: f32) -> Option<ObjectHit> {
    let p0 = Vec3::from_slice(&tri.p0);
    let e1 = Vec3::from_slice(&tri.p1) - p0;
    let e2 = Vec3::from_slice(&tri.p2) - p0;
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let tv = o - p0;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = tv.cross(e1);
    let v = d.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qv) * inv;
    if !(t > t_min && t < t_max) {
        return None;
    }
    let n = Vec3::from_slice(&tri.n0) * (1.0 - u - v)
        + Vec3::from_slice(&tri.n1) * u
        + Vec3::from_slice(&tri.n2) * v;
    Some(ObjectHit {
        t,
        normal: n,
        geometric: e1.cross(e2),
    })
}

/// An analytic shape by kind and parameters (as stored in GpuShape).
pub fn analytic(
    kind: u32,
    params: [f32; 4],
    o: Vec3,
    d: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<ObjectHit> {
    let p = params;
    match kind {
        SHAPE_SPHERE => sphere(o, d, p[0], t_min, t_max),
        SHAPE_BOX => aabox(o, d, Vec3::new(p[0], p[1], p[2]), t_min, t_max),
        SHAPE_CYLINDER => cylinder(o, d, p[0], p[1], t_min, t_max),
        SHAPE_CONE => cone(o, d, p[0], p[1], t_min, t_max),
        SHAPE_QUAD => plane(o, d, Vec2::new(p[0], p[1]), false, t_min, t_max),
        SHAPE_DISK => plane(o, d, Vec2::new(p[0], p[0]), true, t_min, t_max),
        _ => None,
    }
}

/// Slab test: the entry t of the box if the ray meets it within (t_min, t_max).
pub fn ray_box(o: Vec3, inv_d: Vec3, min: Vec3, max: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
    let t1 = (min - o) * inv_d;
    let t2 = (max - o) * inv_d;
    let near = t1.min(t2).max_element().max(t_min);
    let far = t1.max(t2).min_element().min(t_max);
    (near <= far).then_some(near)
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPS: f32 = 1e-5;

    #[test]
    fn sphere_hit_from_outside_and_inside() {
        let h = sphere(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, 1.0, 0.0, f32::MAX).unwrap();
        assert!((h.t - 4.0).abs() < EPS && (h.normal - Vec3::Z).length() < EPS);
        let h = sphere(Vec3::ZERO, Vec3::X, 2.0, 0.0, f32::MAX).unwrap();
        assert!((h.t - 2.0).abs() < EPS, "from inside, the exit");
        // Unnormalized direction: t scales inversely with |d|.
        let h = sphere(
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::NEG_Z * 2.0,
            1.0,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert!((h.t - 2.0).abs() < EPS);
        assert!(sphere(Vec3::new(0.0, 2.0, 5.0), Vec3::NEG_Z, 1.0, 0.0, f32::MAX).is_none());
    }

    #[test]
    fn box_faces_and_normals() {
        let h = aabox(
            Vec3::new(0.2, 0.1, 5.0),
            Vec3::NEG_Z,
            Vec3::new(1.0, 2.0, 0.5),
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert!((h.t - 4.5).abs() < EPS && h.normal == Vec3::Z);
        let h = aabox(
            Vec3::new(0.0, -9.0, 0.0),
            Vec3::Y,
            Vec3::new(1.0, 2.0, 0.5),
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert!((h.t - 7.0).abs() < EPS && h.normal == Vec3::NEG_Y);
    }

    #[test]
    fn cylinder_side_and_caps() {
        let h = cylinder(
            Vec3::new(5.0, 0.3, 0.0),
            Vec3::NEG_X,
            1.0,
            2.0,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert!((h.t - 4.0).abs() < EPS && (h.normal - Vec3::X).length() < EPS);
        let h = cylinder(
            Vec3::new(0.5, 5.0, 0.0),
            Vec3::NEG_Y,
            1.0,
            2.0,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert!((h.t - 4.0).abs() < EPS && h.normal == Vec3::Y);
        assert!(cylinder(
            Vec3::new(5.0, 1.5, 0.0),
            Vec3::NEG_X,
            1.0,
            2.0,
            0.0,
            f32::MAX
        )
        .is_none());
    }

    #[test]
    fn cone_side_and_base() {
        // Cone r = 1, h = 2: at y = 1 the radius is 0.5.
        let h = cone(
            Vec3::new(5.0, 1.0, 0.0),
            Vec3::NEG_X,
            1.0,
            2.0,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert!((h.t - 4.5).abs() < EPS);
        // Outward normal of the side: (1, k, 0) normalized with k = r/h = 0.5.
        assert!((h.normal - Vec3::new(1.0, 0.5, 0.0).normalize()).length() < 1e-5);
        let h = cone(Vec3::new(0.2, -3.0, 0.0), Vec3::Y, 1.0, 2.0, 0.0, f32::MAX).unwrap();
        assert!((h.t - 3.0).abs() < EPS && h.normal == Vec3::NEG_Y);
        assert!(cone(
            Vec3::new(5.0, 2.5, 0.0),
            Vec3::NEG_X,
            1.0,
            2.0,
            0.0,
            f32::MAX
        )
        .is_none());
    }

    #[test]
    fn quad_and_disk_bounds() {
        let down = Vec3::NEG_Y;
        assert!(plane(
            Vec3::new(0.9, 1.0, -1.9),
            down,
            Vec2::new(1.0, 2.0),
            false,
            0.0,
            f32::MAX
        )
        .is_some());
        assert!(plane(
            Vec3::new(1.1, 1.0, 0.0),
            down,
            Vec2::new(1.0, 2.0),
            false,
            0.0,
            f32::MAX
        )
        .is_none());
        assert!(plane(
            Vec3::new(0.7, 1.0, 0.7),
            down,
            Vec2::splat(1.0),
            true,
            0.0,
            f32::MAX
        )
        .is_some());
        assert!(plane(
            Vec3::new(0.75, 1.0, 0.75),
            down,
            Vec2::splat(1.0),
            true,
            0.0,
            f32::MAX
        )
        .is_none());
    }
}
