//! Analytic shapes to triangle meshes.

use std::f64::consts::PI;

use glam::{Vec2, Vec3};

use super::{Mesh, PlaneKind, Shape};

/// Segments around the axis of a tessellated sphere (its finest level, see
/// [`SPHERE_LEVELS`]). The mesh reaches at most [`sphere_inset`] inside the
/// sphere, 0.06% of the radius at 128 segments (the circumradius of an
/// equatorial triangle, half the diagonal of a square of 2 pi / 128
/// radians a side), so its silhouette strays from the true one by at most
/// half a pixel while the sphere's radius on screen is under 800 px.
pub const SPHERE_SEGMENTS: u32 = 128;
/// Rings from pole to pole of a tessellated sphere (same angular step).
pub const SPHERE_RINGS: u32 = 64;
/// The segment counts of a sphere's tessellation levels, finest first
/// (each has half as many rings). Raster mode draws a sphere at the
/// coarsest level whose silhouette stays within
/// [`MAX_SILHOUETTE_ERROR_PX`] of the true one (`render::raster::draw_levels`):
/// a sphere of 100 px radius on screen takes the 64-segment level, a
/// quarter of the finest level's triangles, one of 10 px the 16-segment
/// level, a sixty-fourth.
pub const SPHERE_LEVELS: [u32; 4] = [SPHERE_SEGMENTS, 64, 32, 16];
/// How far, in pixels, a tessellated sphere's silhouette may stray from the
/// true sphere's when raster mode picks its level. Half a pixel: a pixel
/// centre that the true silhouette misses by more than half a pixel is on
/// the same side of the drawn one, so one sample per pixel classifies every
/// pixel but those on the silhouette the same.
pub const MAX_SILHOUETTE_ERROR_PX: f32 = 0.5;
/// Segments around the axis of tessellated cylinders, cones and disks: a
/// circle of R pixels is then within R (1 - cos(pi / 128)) = 0.0003 R of
/// its polygon, under half a pixel while R is under 1,600 px. (They are a
/// few hundred triangles, so they have one level.)
pub const ROUND_SEGMENTS: u32 = 128;

/// Turns a shape into a triangle mesh in object space with smooth
/// per-vertex unit normals and counter-clockwise front faces seen from
/// outside (from +y for planes).
///
/// The resolution keeps silhouettes smooth at 1080p:
/// - sphere: [`SPHERE_SEGMENTS`] x [`SPHERE_RINGS`], normal = position / radius;
/// - cylinder and cone: [`ROUND_SEGMENTS`] segments, caps have their own
///   vertices with flat normals;
/// - box: 24 vertices (4 per face) with face normals, 12 triangles;
/// - plane quad: 4 vertices, 2 triangles; plane disk: [`ROUND_SEGMENTS`] segments.
///
/// [`Shape::Mesh`] returns a clone of the mesh; [`Shape::Csg`] an empty mesh
/// (CSG is ray-traced only, never rasterized).
pub fn tessellate(shape: &Shape) -> Mesh {
    let mut b = match shape {
        Shape::Sphere { radius } => sphere(*radius, SPHERE_SEGMENTS),
        Shape::Box { half_extents } => cuboid(*half_extents),
        Shape::Cylinder { radius, height } => cylinder(*radius, *height),
        Shape::Cone { radius, height } => cone(*radius, *height),
        Shape::Plane(PlaneKind::Quad { half_size }) => quad(*half_size),
        Shape::Plane(PlaneKind::Disk { radius }) => {
            let mut b = Builder::default();
            b.cap(*radius, 0.0, Vec3::Y);
            b
        }
        Shape::Mesh(mesh) => return mesh.clone(),
        Shape::Csg(_) => return Mesh::default(),
    };
    b.mesh.source = format!("tessellated {}", shape.kind_name());
    b.mesh
}

/// A sphere of `radius` with `segments` (even, at least 4) around its axis
/// and `segments / 2` rings: one of the [`SPHERE_LEVELS`].
/// `tessellate(&Shape::Sphere { radius })` is this at [`SPHERE_SEGMENTS`].
pub fn tessellate_sphere(radius: f32, segments: u32) -> Mesh {
    let mut b = sphere(radius, segments.max(4) & !1);
    b.mesh.source = format!("tessellated sphere, {segments} segments");
    b.mesh
}

/// How far inside its sphere (of `radius`, centred on the origin) a
/// tessellated sphere reaches: `radius` less the smallest distance from the
/// centre to the plane of any of its triangles. Every point of the mesh lies
/// between the sphere of `radius - inset` and the true one, so the mesh's
/// silhouette strays from the true one by at most the inset as seen from
/// the camera.
pub fn sphere_inset(mesh: &Mesh, radius: f32) -> f32 {
    let p = |i: u32| mesh.positions[i as usize].as_dvec3();
    let closest = mesh
        .indices
        .chunks_exact(3)
        .map(|t| {
            let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
            let n = (b - a).cross(c - a).normalize_or_zero();
            n.dot(a).abs()
        })
        .fold(f64::from(radius), f64::min);
    (f64::from(radius) - closest).max(0.0) as f32
}

/// Collects vertices and triangles.
#[derive(Default)]
struct Builder {
    mesh: Mesh,
}

impl Builder {
    /// Adds a vertex and returns its index.
    fn vertex(&mut self, position: Vec3, normal: Vec3) -> u32 {
        self.mesh.positions.push(position);
        self.mesh.normals.push(normal);
        (self.mesh.positions.len() - 1) as u32
    }

    fn triangle(&mut self, a: u32, b: u32, c: u32) {
        self.mesh.indices.extend([a, b, c]);
    }

    /// Adds a flat disk of `radius` at height `y` facing `normal`
    /// (+y or -y), with its own vertices.
    fn cap(&mut self, radius: f32, y: f32, normal: Vec3) {
        let center = self.vertex(Vec3::new(0.0, y, 0.0), normal);
        let first = center + 1;
        for s in 0..ROUND_SEGMENTS {
            let (cos, sin) = unit_circle(s, ROUND_SEGMENTS);
            self.vertex(Vec3::new(radius * cos, y, radius * sin), normal);
        }
        for s in 0..ROUND_SEGMENTS {
            let v0 = first + s;
            let v1 = first + (s + 1) % ROUND_SEGMENTS;
            if normal.y > 0.0 {
                self.triangle(center, v1, v0);
            } else {
                self.triangle(center, v0, v1);
            }
        }
    }
}

/// `(cos, sin)` of the angle `2 pi i / n`, computed in f64 so that
/// positions land exactly on the circle.
fn unit_circle(i: u32, n: u32) -> (f32, f32) {
    let angle = 2.0 * PI * f64::from(i) / f64::from(n);
    (angle.cos() as f32, angle.sin() as f32)
}

/// UV sphere with one vertex at each pole. Angle theta runs around +y from
/// +x towards +z; rings run from the north (+y) to the south pole.
fn sphere(radius: f32, segments: u32) -> Builder {
    let rings = segments / 2;
    let mut b = Builder::default();
    let north = b.vertex(Vec3::new(0.0, radius, 0.0), Vec3::Y);
    for r in 1..rings {
        let phi = PI * f64::from(r) / f64::from(rings);
        let (sin_phi, cos_phi) = (phi.sin() as f32, phi.cos() as f32);
        for s in 0..segments {
            let (cos, sin) = unit_circle(s, segments);
            let n = Vec3::new(sin_phi * cos, cos_phi, sin_phi * sin);
            b.vertex(n * radius, n);
        }
    }
    let south = b.vertex(Vec3::new(0.0, -radius, 0.0), -Vec3::Y);
    // Index of the vertex at ring r (1..rings) and segment s.
    let at = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    for s in 0..segments {
        b.triangle(north, at(1, s + 1), at(1, s));
        for r in 1..rings - 1 {
            let (a, c) = (at(r, s), at(r + 1, s));
            let (a1, c1) = (at(r, s + 1), at(r + 1, s + 1));
            b.triangle(a, a1, c);
            b.triangle(a1, c1, c);
        }
        b.triangle(at(rings - 1, s), at(rings - 1, s + 1), south);
    }
    b
}

/// Box with 4 vertices per face and face normals.
fn cuboid(half: Vec3) -> Builder {
    // (normal, u, v) with u x v = normal, so (-u-v, +u-v, +u+v, -u+v)
    // is counter-clockwise seen from outside.
    const FACES: [(Vec3, Vec3, Vec3); 6] = [
        (Vec3::X, Vec3::Y, Vec3::Z),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::Z, Vec3::X),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::Y, Vec3::X),
    ];
    let mut b = Builder::default();
    for (n, u, v) in FACES {
        let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
        let first = b.mesh.positions.len() as u32;
        for (su, sv) in corners {
            b.vertex((n + su * u + sv * v) * half, n);
        }
        b.triangle(first, first + 1, first + 2);
        b.triangle(first, first + 2, first + 3);
    }
    b
}

/// Capped cylinder around +y from `-height / 2` to `height / 2`.
fn cylinder(radius: f32, height: f32) -> Builder {
    let n = ROUND_SEGMENTS;
    let (top_y, bottom_y) = (height / 2.0, -height / 2.0);
    let mut b = Builder::default();
    let first = b.mesh.positions.len() as u32;
    for s in 0..n {
        let (cos, sin) = unit_circle(s, n);
        let normal = Vec3::new(cos, 0.0, sin);
        b.vertex(Vec3::new(radius * cos, top_y, radius * sin), normal);
        b.vertex(Vec3::new(radius * cos, bottom_y, radius * sin), normal);
    }
    let top = |s: u32| first + 2 * (s % n);
    let bottom = |s: u32| first + 2 * (s % n) + 1;
    for s in 0..n {
        b.triangle(top(s), top(s + 1), bottom(s));
        b.triangle(top(s + 1), bottom(s + 1), bottom(s));
    }
    b.cap(radius, top_y, Vec3::Y);
    b.cap(radius, bottom_y, Vec3::NEG_Y);
    b
}

/// Cone around +y: base disk at y = 0, apex at y = `height`.
///
/// The apex is split into one vertex per segment whose normal is the
/// surface normal at the middle of that segment.
fn cone(radius: f32, height: f32) -> Builder {
    let n = ROUND_SEGMENTS;
    // The outward surface normal at angle (cos, sin) is proportional to
    // (height * cos, radius, height * sin).
    let side_normal =
        |cos: f32, sin: f32| Vec3::new(height * cos, radius, height * sin).normalize_or(Vec3::Y);
    let mut b = Builder::default();
    let base_first = b.mesh.positions.len() as u32;
    for s in 0..n {
        let (cos, sin) = unit_circle(s, n);
        b.vertex(
            Vec3::new(radius * cos, 0.0, radius * sin),
            side_normal(cos, sin),
        );
    }
    let apex_first = b.mesh.positions.len() as u32;
    for s in 0..n {
        let (cos, sin) = unit_circle(2 * s + 1, 2 * n);
        b.vertex(Vec3::new(0.0, height, 0.0), side_normal(cos, sin));
    }
    for s in 0..n {
        b.triangle(apex_first + s, base_first + (s + 1) % n, base_first + s);
    }
    b.cap(radius, 0.0, Vec3::NEG_Y);
    b
}

/// Rectangle in the xz plane facing +y.
fn quad(half: Vec2) -> Builder {
    let mut b = Builder::default();
    for (x, z) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, 1.0), (1.0, -1.0)] {
        b.vertex(Vec3::new(x * half.x, 0.0, z * half.y), Vec3::Y);
    }
    b.triangle(0, 1, 2);
    b.triangle(0, 2, 3);
    b
}
