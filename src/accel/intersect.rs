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

/// How far (relative to the magnitudes in play) the triangle test's edge
/// values may stray below zero and still count as inside: a ray through a
/// shared edge or vertex then finds at least one of the triangles there,
/// whatever the rounding. The edge values' error is a few roundings of
/// coordinates as large as `m`, the largest of the ray origin and the
/// mesh's bounds (max norm), times the sheared coordinates' size: about 4
/// ulp of m per coordinate; 1e-6 (17 ulp) covers it with room for GPU
/// compilers, which may fuse multiply-adds and reorder sums where WGSL gives
/// no way to forbid it. Exact schemes that rely on the very same
/// arithmetic in two triangles (Woop et al.'s, with an antisymmetric edge
/// formula and a top-left rule) held on lavapipe and the CPU but still
/// left the diagonal of a head-on quad unhit on an NVIDIA H200 (32 of 3,600
/// pixels); a tolerance of 1e-6 of |q.x p.y| + |q.y p.x|, smaller than this
/// one, closed it there.
/// shaders/lib/intersect.wgsl reads it from the generated lib/limits.wgsl
/// and applies it where its override `EDGE_TOLERANCE` is on: not on CPU
/// adapters, where exact comparisons are watertight and the tolerance cost a
/// fifth of a trace pass (`Gpu::set_edge_tolerance`). This CPU reference
/// always applies it.
pub const EDGE_SLACK: f32 = 1e-6;

/// A ray prepared for [`triangle`]: the ray-triangle test of Woop, Benthin
/// and Wald (2013, "Watertight Ray/Triangle Intersection"), with a
/// tolerance. Vertices are moved into a sheared frame where the ray is the
/// z axis through (0, 0), each vertex on its own, and a triangle is hit
/// where its three edge values there have one sign, each allowed to miss
/// zero by [`EDGE_SLACK`] of the magnitudes in play: so a ray through a
/// shared edge or vertex finds at least one of the triangles there (tests/
/// raytrace.rs, rays_through_edges_and_vertices_never_slip_through), where
/// Möller-Trumbore, or the test without tolerance on a GPU, found none (a
/// crack). Two triangles may both be hit at an edge, at the same t: the
/// closest-hit walk keeps one, and a CSG leaf's crossings ignore a repeated
/// entry (`mesh_crossings`).
#[derive(Debug, Clone, Copy)]
pub struct TriangleRay {
    o: Vec3,
    /// Rows of the shear: x = a[kx] - a[kz] d[kx] / d[kz],
    /// y = a[ky] - a[kz] d[ky] / d[kz], z = a[kz] / d[kz] (= t in the
    /// vertex's z plane), for a = vertex - o and kz the dominant axis of d.
    rx: Vec3,
    ry: Vec3,
    rz: Vec3,
    /// EDGE_SLACK times the largest coordinate in play (max norm of the
    /// origin and of the mesh's bounds).
    slack: f32,
}

impl TriangleRay {
    /// The ray (o, d) against a mesh whose triangles lie in the box
    /// (`bounds_min`, `bounds_max`).
    pub fn new(o: Vec3, d: Vec3, bounds_min: Vec3, bounds_max: Vec3) -> Self {
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        // Keep the winding: a triangle facing the ray turns the same way.
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let axis = |k: usize| Vec3::AXES[k];
        let (sx, sy, sz) = (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
        let m = o
            .abs()
            .max(bounds_min.abs())
            .max(bounds_max.abs())
            .max_element();
        Self {
            o,
            rx: axis(kx) - axis(kz) * sx,
            ry: axis(ky) - axis(kz) * sy,
            rz: axis(kz) * sz,
            slack: EDGE_SLACK * m,
        }
    }

    fn sheared(&self, p: [f32; 4]) -> Vec3 {
        let a = Vec3::from_slice(&p[..3]) - self.o;
        Vec3::new(a.dot(self.rx), a.dot(self.ry), a.dot(self.rz))
    }
}

/// The ray-triangle test (see [`TriangleRay`]): t and the barycentric
/// weights (u, v) of p1 and p2, or None.
pub fn triangle_tuv(ray: &TriangleRay, tri: &GpuTriangle, t_min: f32, t_max: f32) -> Option<Vec3> {
    let (a, b, c) = (
        ray.sheared(tri.p0),
        ray.sheared(tri.p1),
        ray.sheared(tri.p2),
    );
    // Each vertex's weight is the edge value opposite it: twice the signed
    // area of (0, p, q) for the edge p -> q, q.x p.y - q.y p.x.
    let u = c.x * b.y - c.y * b.x;
    let v = a.x * c.y - a.y * c.x;
    let w = b.x * a.y - b.y * a.x;
    // The tolerance of an edge value grows with its endpoints' size.
    let size = |p: Vec3| p.x.abs() + p.y.abs();
    let (la, lb, lc) = (size(a), size(b), size(c));
    let (tu, tv, tw) = (
        ray.slack * (lb + lc),
        ray.slack * (lc + la),
        ray.slack * (la + lb),
    );
    let facing = u >= -tu && v >= -tv && w >= -tw;
    let away = u <= tu && v <= tv && w <= tw;
    let det = u + v + w;
    if !(facing || away) || det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let t = (u * a.z + v * b.z + w * c.z) * inv;
    if !(t > t_min && t < t_max) {
        return None;
    }
    Some(Vec3::new(t, v * inv, w * inv))
}

/// The hit on a triangle ([`triangle_tuv`]); the
/// shading normal interpolates the vertex normals by the barycentric
/// weights (as the rasterizer does).
pub fn triangle(ray: &TriangleRay, tri: &GpuTriangle, t_min: f32, t_max: f32) -> Option<ObjectHit> {
    let tuv = triangle_tuv(ray, tri, t_min, t_max)?;
    let (u, v) = (tuv.y, tuv.z);
    let p0 = Vec3::from_slice(&tri.p0[..3]);
    let e1 = Vec3::from_slice(&tri.p1[..3]) - p0;
    let e2 = Vec3::from_slice(&tri.p2[..3]) - p0;
    let n = Vec3::from_slice(&tri.n0[..3]) * (1.0 - u - v)
        + Vec3::from_slice(&tri.n1[..3]) * u
        + Vec3::from_slice(&tri.n2[..3]) * v;
    Some(ObjectHit {
        t: tuv.x,
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

/// How far a box's exit t is pushed out (relative) so that rounding never
/// culls a box the ray touches. Each slab t is rounded in the subtraction,
/// the reciprocal (Vulkan allows 2.5 ulp for 1/x) and the product: about 4
/// ulp, 4.8e-7, at each end; 1e-6 covers both ends. A ray through a vertex
/// or an edge on a box's face meets it at one t (near = far exactly), and
/// without this a rounding of either end dropped the box and the triangle
/// that owns the point (Ize 2013, "Robust BVH Ray Traversal", does the same
/// with its own bound). shaders/lib/traverse.wgsl (node_span) reads it from
/// the generated lib/limits.wgsl.
pub const BOX_EXIT_SLACK: f32 = 1e-6;

/// Slab test: the entry t of the box if the ray meets it within (t_min,
/// t_max), the exit pushed out by [`BOX_EXIT_SLACK`].
pub fn ray_box(o: Vec3, inv_d: Vec3, min: Vec3, max: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
    let t1 = (min - o) * inv_d;
    let t2 = (max - o) * inv_d;
    let near = t1.min(t2).max_element().max(t_min);
    let exit = t1.max(t2).min_element();
    let slack = if exit < 0.0 {
        1.0 - BOX_EXIT_SLACK
    } else {
        1.0 + BOX_EXIT_SLACK
    };
    let far = (exit * slack).min(t_max);
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
