// Exact ray-shape intersection in object space: the WGSL twin of
// src/accel/intersect.rs (same formulas in the same order).
// Rays are (o, d) with d NOT normalized: an instance's ray is the world ray
// mapped by the inverse matrix, so t is the same in both spaces. Each
// function returns the nearest t in (t_min, t_max) and the outward
// object-space normal there (planes: +y).

const SHAPE_SPHERE: u32 = 0u;
const SHAPE_BOX: u32 = 1u;
const SHAPE_CYLINDER: u32 = 2u;
const SHAPE_CONE: u32 = 3u;
const SHAPE_QUAD: u32 = 4u;
const SHAPE_DISK: u32 = 5u;
const SHAPE_MESH: u32 = 6u;

struct ObjectHit {
    hit: bool,
    t: f32,
    normal: vec3<f32>,
    // Outward geometric normal (triangles: by counter-clockwise winding).
    geometric: vec3<f32>,
}

fn object_hit(t: f32, n: vec3<f32>) -> ObjectHit {
    return ObjectHit(true, t, n, n);
}

fn no_hit() -> ObjectHit {
    return ObjectHit(false, 0.0, vec3<f32>(0.0), vec3<f32>(0.0));
}

fn in_range(t: f32, t_min: f32, t_max: f32) -> bool {
    return t > t_min && t < t_max;
}

fn intersect_sphere(o: vec3<f32>, d: vec3<f32>, r: f32, t_min: f32, t_max: f32) -> ObjectHit {
    let a = dot(d, d);
    let b = dot(o, d);
    let c = dot(o, o) - r * r;
    let disc = b * b - a * c;
    if disc < 0.0 {
        return no_hit();
    }
    let s = sqrt(disc);
    var t = (-b - s) / a;
    if !in_range(t, t_min, t_max) {
        t = (-b + s) / a;
        if !in_range(t, t_min, t_max) {
            return no_hit();
        }
    }
    return object_hit(t, (o + d * t) / r);
}

fn intersect_box(o: vec3<f32>, d: vec3<f32>, h: vec3<f32>, t_min: f32, t_max: f32) -> ObjectHit {
    let inv = 1.0 / d;
    let t1 = (-h - o) * inv;
    let t2 = (h - o) * inv;
    let lo = min(t1, t2);
    let hi = max(t1, t2);
    let near = max(max(lo.x, lo.y), lo.z);
    let far = min(min(hi.x, hi.y), hi.z);
    if near > far {
        return no_hit();
    }
    var t = near;
    if !in_range(t, t_min, t_max) {
        t = far;
        if !in_range(t, t_min, t_max) {
            return no_hit();
        }
    }
    return object_hit(t, box_normal((o + d * t) / h));
}

// The outward normal of the unit box at p (box space divided by the half
// extents): the axis p is farthest along.
fn box_normal(p: vec3<f32>) -> vec3<f32> {
    let a = abs(p);
    var n = vec3<f32>(0.0, 0.0, sign(p.z));
    if a.x >= a.y && a.x >= a.z {
        n = vec3<f32>(sign(p.x), 0.0, 0.0);
    } else if a.y >= a.z {
        n = vec3<f32>(0.0, sign(p.y), 0.0);
    }
    return n;
}

fn intersect_cylinder(o: vec3<f32>, d: vec3<f32>, r: f32, height: f32, t_min: f32, t_max: f32) -> ObjectHit {
    let half = height * 0.5;
    var best = no_hit();
    var t_far = t_max;
    let a = d.x * d.x + d.z * d.z;
    if a > 0.0 {
        let b = o.x * d.x + o.z * d.z;
        let c = o.x * o.x + o.z * o.z - r * r;
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let s = sqrt(disc);
            let roots = array<f32, 2>((-b - s) / a, (-b + s) / a);
            for (var i = 0; i < 2; i++) {
                let t = roots[i];
                let y = o.y + d.y * t;
                if t > t_min && t < t_far && abs(y) <= half {
                    let p = o + d * t;
                    best = object_hit(t, vec3<f32>(p.x, 0.0, p.z) / r);
                    t_far = t;
                    break;
                }
            }
        }
    }
    if d.y != 0.0 {
        let caps = array<f32, 2>(half, -half);
        for (var i = 0; i < 2; i++) {
            let cap = caps[i];
            let t = (cap - o.y) / d.y;
            let p = o + d * t;
            if t > t_min && t < t_far && p.x * p.x + p.z * p.z <= r * r {
                best = object_hit(t, vec3<f32>(0.0, sign(cap), 0.0));
                t_far = t;
            }
        }
    }
    return best;
}

fn intersect_cone(o: vec3<f32>, d: vec3<f32>, r: f32, height: f32, t_min: f32, t_max: f32) -> ObjectHit {
    let k = r / height;
    let k2 = k * k;
    var best = no_hit();
    var t_far = t_max;
    let hy = height - o.y;
    let a = d.x * d.x + d.z * d.z - k2 * d.y * d.y;
    let b = o.x * d.x + o.z * d.z + k2 * hy * d.y;
    let c = o.x * o.x + o.z * o.z - k2 * hy * hy;
    var roots = array<f32, 2>(-1.0, -1.0);
    var count = 0;
    if abs(a) > 1e-12 {
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let s = sqrt(disc);
            let r0 = (-b - s) / a;
            let r1 = (-b + s) / a;
            roots = array<f32, 2>(min(r0, r1), max(r0, r1));
            count = 2;
        }
    } else if abs(b) > 1e-12 {
        roots[0] = -c / (2.0 * b);
        count = 1;
    }
    for (var i = 0; i < count; i++) {
        let t = roots[i];
        let p = o + d * t;
        if t > t_min && t < t_far && p.y >= 0.0 && p.y <= height {
            best = object_hit(t, normalize(vec3<f32>(p.x, k2 * (height - p.y), p.z)));
            t_far = t;
            break;
        }
    }
    if d.y != 0.0 {
        let t = -o.y / d.y;
        let p = o + d * t;
        if t > t_min && t < t_far && p.x * p.x + p.z * p.z <= r * r {
            best = object_hit(t, vec3<f32>(0.0, -1.0, 0.0));
        }
    }
    return best;
}

fn intersect_plane(o: vec3<f32>, d: vec3<f32>, half: vec2<f32>, disk: bool, t_min: f32, t_max: f32) -> ObjectHit {
    if d.y == 0.0 {
        return no_hit();
    }
    let t = -o.y / d.y;
    if !in_range(t, t_min, t_max) {
        return no_hit();
    }
    let p = o + d * t;
    var inside = abs(p.x) <= half.x && abs(p.z) <= half.y;
    if disk {
        inside = p.x * p.x + p.z * p.z <= half.x * half.x;
    }
    if inside {
        return object_hit(t, vec3<f32>(0.0, 1.0, 0.0));
    }
    return no_hit();
}

// Whether triangle_tuv gives its edge values a tolerance. Off in
// pipelines for CPU adapters (Gpu::edge_tolerance_constant): there the edge
// values are compared exactly, which is watertight on lavapipe, and the
// tolerance's arithmetic cost a fifth of the default scene's trace pass.
override EDGE_TOLERANCE: bool = true;

// A ray prepared for the ray-triangle test of Woop, Benthin and Wald
// (2013) with a tolerance: the twin of TriangleRay in
// src/accel/intersect.rs (same formulas, same order; EDGE_SLACK there says
// why the tolerance). Vertices move into a sheared frame where the ray is
// the z axis through (0, 0): x = a[kx] - a[kz] d[kx] / d[kz],
// y = a[ky] - a[kz] d[ky] / d[kz], z = a[kz] / d[kz] (t in the vertex's z
// plane), for a = vertex - o and kz the dominant axis of d. A triangle is
// hit where its three edge values have one sign, each allowed to miss zero
// by EDGE_SLACK of the magnitudes in play where EDGE_TOLERANCE is on
// (exact comparisons on lavapipe), so a ray through a shared edge or vertex
// finds at least one of the triangles there (Moller-Trumbore and
// the exact test both left the diagonal of a head-on quad unhit on an
// NVIDIA GPU, which fuses multiply-adds).
struct TriangleRay {
    o: vec3<f32>,
    rx: vec3<f32>,
    ry: vec3<f32>,
    rz: vec3<f32>,
    // EDGE_SLACK times the largest coordinate in play (max norm of the
    // origin and of the mesh's bounds).
    slack: f32,
}

fn axis_vector(k: u32) -> vec3<f32> {
    return vec3<f32>(f32(k == 0u), f32(k == 1u), f32(k == 2u));
}

// The ray (o, d) against a mesh whose triangles lie in the box (lo, hi).
fn triangle_ray(o: vec3<f32>, d: vec3<f32>, lo: vec3<f32>, hi: vec3<f32>) -> TriangleRay {
    let a = abs(d);
    let kz = select(select(2u, 1u, a.y >= a.z), 0u, a.x >= a.y && a.x >= a.z);
    // Keep the winding: a triangle facing the ray turns the same way.
    let flip = d[kz] < 0.0;
    let kx = select((kz + 1u) % 3u, (kz + 2u) % 3u, flip);
    let ky = select((kz + 2u) % 3u, (kz + 1u) % 3u, flip);
    let ez = axis_vector(kz);
    let m3 = max(abs(o), max(abs(lo), abs(hi)));
    let m = max(max(m3.x, m3.y), m3.z);
    return TriangleRay(o, axis_vector(kx) - ez * (d[kx] / d[kz]), axis_vector(ky) - ez * (d[ky] / d[kz]), ez * (1.0 / d[kz]), EDGE_SLACK * m);
}

fn sheared(r: TriangleRay, p: vec3<f32>) -> vec3<f32> {
    let a = p - r.o;
    return vec3<f32>(dot(a, r.rx), dot(a, r.ry), dot(a, r.rz));
}

// Triangle k of `triangles` against the prepared ray: (t, u, v, 1) with
// u, v the barycentric weights of p1 and p2, or w = 0 where the ray misses
// it within (t_min, t_max). It reads only the corners: a traversal tests
// many triangles and needs the normals of its closest hit alone
// (triangle_hit), and on the CPU driver every field read is a gather.
//
// Without branches: every test is computed and the answer selected once.
// The CPU driver runs 8 invocations as one program, and each early return
// cost a mask update and an any-lane check on every triangle; the tests
// with non-short-circuit `&` and `|` (WGSL's `&&` and `||` branch) took
// 4-7% off mesh ray batches and 2-3% off trace passes with meshes
// (docs/performance-history.md, thirteenth session). Same arithmetic, same answers.
fn triangle_tuv(r: TriangleRay, k: u32, t_min: f32, t_max: f32) -> vec4<f32> {
    return corners_tuv(r, triangles[k].p0.xyz, triangles[k].p1.xyz, triangles[k].p2.xyz, t_min, t_max);
}

// triangle_tuv on the triangle's corners (p0, p1, p2), however they were read.
fn corners_tuv(r: TriangleRay, p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>, t_min: f32, t_max: f32) -> vec4<f32> {
    let a = sheared(r, p0);
    let b = sheared(r, p1);
    let c = sheared(r, p2);
    // Each vertex's weight is the edge value opposite it: twice the signed
    // area of (0, p, q) for the edge p -> q, q.x p.y - q.y p.x.
    let u = c.x * b.y - c.y * b.x;
    let v = a.x * c.y - a.y * c.x;
    let w = b.x * a.y - b.y * a.x;
    var facing = (u >= 0.0) & (v >= 0.0) & (w >= 0.0);
    var away = (u <= 0.0) & (v <= 0.0) & (w <= 0.0);
    if EDGE_TOLERANCE {
        // The tolerance of an edge value grows with its endpoints' size.
        let la = abs(a.x) + abs(a.y);
        let lb = abs(b.x) + abs(b.y);
        let lc = abs(c.x) + abs(c.y);
        let tu = r.slack * (lb + lc);
        let tv = r.slack * (lc + la);
        let tw = r.slack * (la + lb);
        facing = (u >= -tu) & (v >= -tv) & (w >= -tw);
        away = (u <= tu) & (v <= tv) & (w <= tw);
    }
    let det = u + v + w;
    let inv = 1.0 / det;
    let t = (u * a.z + v * b.z + w * c.z) * inv;
    // The same comparisons as the CPU twin's early returns (NaN included).
    let inside = (facing | away) & (det != 0.0) & (t > t_min) & (t < t_max);
    return select(vec4<f32>(0.0), vec4<f32>(t, v * inv, w * inv, 1.0), inside);
}

// The hit on triangle k at (t, u, v) from triangle_tuv: the shading normal
// interpolates the vertex normals by the barycentric coordinates, as the
// rasterizer does; the geometric normal follows the winding.
fn triangle_hit(k: u32, tuv: vec3<f32>) -> ObjectHit {
    let p0 = triangles[k].p0.xyz;
    let e1 = triangles[k].p1.xyz - p0;
    let e2 = triangles[k].p2.xyz - p0;
    let u = tuv.y;
    let v = tuv.z;
    let n = triangles[k].n0.xyz * (1.0 - u - v) + triangles[k].n1.xyz * u + triangles[k].n2.xyz * v;
    return ObjectHit(true, tuv.x, n, cross(e1, e2));
}

// Triangle k's hit, or no_hit().
fn intersect_triangle(r: TriangleRay, k: u32, t_min: f32, t_max: f32) -> ObjectHit {
    let h = triangle_tuv(r, k, t_min, t_max);
    if h.w == 0.0 {
        return no_hit();
    }
    return triangle_hit(k, h.xyz);
}

// The analytic shape kinds the scene holds (bit 1 << kind), at the top
// level or as CSG leaves, fixed per pipeline (trace.rs Variant): the
// intersection code of the others is left out. Pipelines that do not set
// it hold every kind.
override ANALYTIC_KINDS: u32 = 0x3fu;

fn has_kind(kind: u32) -> bool {
    return (ANALYTIC_KINDS & (1u << kind)) != 0u;
}

fn intersect_analytic(kind: u32, p: vec4<f32>, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> ObjectHit {
    switch kind {
        case SHAPE_SPHERE: {
            if has_kind(SHAPE_SPHERE) {
                return intersect_sphere(o, d, p.x, t_min, t_max);
            }
        }
        case SHAPE_BOX: {
            if has_kind(SHAPE_BOX) {
                return intersect_box(o, d, p.xyz, t_min, t_max);
            }
        }
        case SHAPE_CYLINDER: {
            if has_kind(SHAPE_CYLINDER) {
                return intersect_cylinder(o, d, p.x, p.y, t_min, t_max);
            }
        }
        case SHAPE_CONE: {
            if has_kind(SHAPE_CONE) {
                return intersect_cone(o, d, p.x, p.y, t_min, t_max);
            }
        }
        case SHAPE_QUAD: {
            if has_kind(SHAPE_QUAD) {
                return intersect_plane(o, d, p.xy, false, t_min, t_max);
            }
        }
        case SHAPE_DISK: {
            if has_kind(SHAPE_DISK) {
                return intersect_plane(o, d, p.xx, true, t_min, t_max);
            }
        }
        default: {}
    }
    return no_hit();
}
