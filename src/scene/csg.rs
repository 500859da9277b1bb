//! Constructive solid geometry trees: a [`Shape::Csg`](super::Shape::Csg)
//! combines solids (analytic shapes and closed meshes, each with its own
//! transform and optional material) with union, intersection and difference.
//!
//! The renderer evaluates a tree per ray by intervals (see `accel::csg`):
//! every leaf yields the spans of t where the ray is inside it, the tree
//! combines the spans with the same set operations, and the boundaries of the
//! result are the hits. The GPU keeps a fixed number of intervals per stack
//! entry, so every tree is checked at load ([`Csg::check`]) against
//! [`CSG_MAX_INTERVALS`] and [`CSG_STACK`]: a tree that could exceed them is
//! refused with a message, never rendered wrong.
//!
//! Worst-case interval counts, bottom up (the counts hold for any ray):
//! - a convex analytic leaf (sphere, box, cylinder, cone): 1;
//! - a mesh leaf: [`CSG_MESH_MAX_CROSSINGS`] / 2 (a ray meeting the mesh more
//!   often than that is reported as an overflow, drawn magenta and counted,
//!   like a traversal overflow);
//! - `Union`: the sum of its children's counts;
//! - `Intersection`: the sum minus (children - 1) (`|A n B| <= |A| + |B| - 1`);
//! - `Difference(a, b)`: `a + b` (each interval of b splits at most one of a).
//!
//! Planes and disks have no inside and are refused as leaves (use a thin
//! box).

use glam::{DMat3, DMat4, DVec3, Mat4, Vec3};

use super::{Mesh, Shape};

// The CSG limits' one home: `accel::csg` (CPU) uses them from here, and
// WGSL gets them from the header `gpu::shader::limits_header` generates.

/// Intervals one stack entry of the CSG evaluator holds (GPU and CPU).
pub const CSG_MAX_INTERVALS: u32 = 8;
/// Stack entries of the CSG evaluator; a tree needing more is refused.
pub const CSG_STACK: u32 = 4;
/// Ray-mesh crossings a mesh leaf keeps per ray (K); its interval bound is
/// half of it.
pub const CSG_MESH_MAX_CROSSINGS: u32 = 8;

/// A CSG solid: a tree whose leaves are solids in the tree's object space.
#[derive(Debug, Clone, PartialEq)]
pub struct Csg {
    pub root: Box<CsgNode>,
}

/// A node of a CSG tree.
// A leaf holds its shape inline (a mesh's vectors and maps make it the
// large variant); trees are small, so boxing would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum CsgNode {
    /// Points in any child (at least one child).
    Union(Vec<CsgNode>),
    /// Points in every child (at least one child).
    Intersection(Vec<CsgNode>),
    /// Points in the first solid and not in the second.
    Difference(Box<CsgNode>, Box<CsgNode>),
    Leaf(CsgLeaf),
}

/// A solid at the bottom of a tree.
#[derive(Debug, Clone, PartialEq)]
pub struct CsgLeaf {
    /// Sphere, box, cylinder, cone or a closed mesh (never a plane or CSG).
    pub shape: Shape,
    /// Leaf space to the CSG shape's object space: affine and invertible.
    pub csg_from_leaf: Mat4,
    /// Material id of the surfaces this leaf contributes; `None`: the
    /// instance's material.
    pub material: Option<usize>,
}

impl CsgNode {
    /// Worst-case number of disjoint intervals a ray can have inside this
    /// node (see the module docs).
    pub fn interval_bound(&self) -> u32 {
        match self {
            CsgNode::Leaf(leaf) => match leaf.shape {
                Shape::Mesh(_) => CSG_MESH_MAX_CROSSINGS / 2,
                _ => 1,
            },
            CsgNode::Union(children) => children.iter().map(CsgNode::interval_bound).sum(),
            CsgNode::Intersection(children) => {
                let sum: u32 = children.iter().map(CsgNode::interval_bound).sum();
                sum.saturating_sub(children.len().saturating_sub(1) as u32)
                    .max(1)
            }
            CsgNode::Difference(a, b) => a.interval_bound() + b.interval_bound(),
        }
    }

    /// Stack entries the postfix program of this node needs when, at each
    /// binary step, the operand needing more is evaluated first.
    pub fn stack_need(&self) -> u32 {
        fn pair(first: u32, second: u32) -> u32 {
            let (big, small) = (first.max(second), first.min(second));
            big.max(small + 1)
        }
        match self {
            CsgNode::Leaf(_) => 1,
            CsgNode::Union(children) | CsgNode::Intersection(children) => {
                let mut iter = children.iter().map(CsgNode::stack_need);
                let first = iter.next().unwrap_or(1);
                iter.fold(first, pair)
            }
            CsgNode::Difference(a, b) => pair(a.stack_need(), b.stack_need()),
        }
    }

    /// Depth of the tree (a leaf is 1).
    pub fn depth(&self) -> u32 {
        match self {
            CsgNode::Leaf(_) => 1,
            CsgNode::Union(c) | CsgNode::Intersection(c) => {
                1 + c.iter().map(CsgNode::depth).max().unwrap_or(0)
            }
            CsgNode::Difference(a, b) => 1 + a.depth().max(b.depth()),
        }
    }

    /// The leaves, left to right.
    pub fn leaves(&self) -> Vec<&CsgLeaf> {
        let mut out = Vec::new();
        self.collect_leaves(&mut out);
        out
    }

    fn collect_leaves<'a>(&'a self, out: &mut Vec<&'a CsgLeaf>) {
        match self {
            CsgNode::Leaf(l) => out.push(l),
            CsgNode::Union(c) | CsgNode::Intersection(c) => {
                c.iter().for_each(|n| n.collect_leaves(out))
            }
            CsgNode::Difference(a, b) => {
                a.collect_leaves(out);
                b.collect_leaves(out);
            }
        }
    }

    /// A conservative object-space box `(min, max)`; empty (min > max) when
    /// the node is provably empty.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        match self {
            CsgNode::Leaf(leaf) => {
                let (a, b) = leaf.shape.bounds();
                let mut lo = Vec3::splat(f32::INFINITY);
                let mut hi = Vec3::splat(f32::NEG_INFINITY);
                for i in 0..8 {
                    let corner = Vec3::new(
                        if i & 1 == 0 { a.x } else { b.x },
                        if i & 2 == 0 { a.y } else { b.y },
                        if i & 4 == 0 { a.z } else { b.z },
                    );
                    let p = leaf.csg_from_leaf.transform_point3(corner);
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
                (lo, hi)
            }
            CsgNode::Union(c) => c.iter().map(CsgNode::bounds).fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), (a, b)| (lo.min(a), hi.max(b)),
            ),
            CsgNode::Intersection(c) => c.iter().map(CsgNode::bounds).fold(
                (Vec3::splat(f32::NEG_INFINITY), Vec3::splat(f32::INFINITY)),
                |(lo, hi), (a, b)| (lo.max(a), hi.min(b)),
            ),
            CsgNode::Difference(a, _) => a.bounds(),
        }
    }

    /// A conservative object-space bounding sphere `(centre, radius)`:
    /// every leaf's sphere carried through its transform; a union encloses
    /// its children's, an intersection keeps the smallest child's, a
    /// difference its first operand's (the solid lies inside it).
    fn bounding_sphere(&self) -> (DVec3, f64) {
        match self {
            CsgNode::Leaf(leaf) => {
                let (c, r) = match &leaf.shape {
                    Shape::Sphere { radius } => (DVec3::ZERO, f64::from(*radius)),
                    shape => {
                        let (lo, hi) = shape.bounds();
                        let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
                        ((lo + hi) / 2.0, (hi - lo).length() / 2.0)
                    }
                };
                let m = leaf.csg_from_leaf.as_dmat4();
                (m.transform_point3(c), r * stretch_bound(&m))
            }
            CsgNode::Union(c) => c
                .iter()
                .map(CsgNode::bounding_sphere)
                .reduce(enclose)
                .expect("a union has children (checked at load)"),
            CsgNode::Intersection(c) => c
                .iter()
                .map(CsgNode::bounding_sphere)
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .expect("an intersection has children (checked at load)"),
            CsgNode::Difference(a, _) => a.bounding_sphere(),
        }
    }

    /// Point membership (the tree's point test): is `p` (object space)
    /// inside the solid? Mesh leaves count crossings of a ray along +x.
    pub fn contains(&self, p: Vec3) -> bool {
        match self {
            CsgNode::Leaf(leaf) => leaf_contains(leaf, p),
            CsgNode::Union(c) => c.iter().any(|n| n.contains(p)),
            CsgNode::Intersection(c) => c.iter().all(|n| n.contains(p)),
            CsgNode::Difference(a, b) => a.contains(p) && !b.contains(p),
        }
    }
}

/// An upper bound of how much the linear part of `m` can stretch a length:
/// the square root of a Gershgorin bound of the largest eigenvalue of
/// `A^T A` (exact for a rotation with uniform scale).
fn stretch_bound(m: &DMat4) -> f64 {
    let a = DMat3::from_mat4(*m);
    let ata = a.transpose() * a;
    let rows = [ata.row(0), ata.row(1), ata.row(2)];
    rows.iter()
        .map(|r| r.abs().element_sum())
        .fold(0.0, f64::max)
        .sqrt()
}

/// The smallest sphere enclosing spheres `a` and `b`.
fn enclose(a: (DVec3, f64), b: (DVec3, f64)) -> (DVec3, f64) {
    let d = (b.0 - a.0).length();
    if d + b.1 <= a.1 {
        return a;
    }
    if d + a.1 <= b.1 {
        return b;
    }
    let r = (d + a.1 + b.1) / 2.0;
    (a.0 + (b.0 - a.0) * ((r - a.1) / d), r)
}

fn leaf_contains(leaf: &CsgLeaf, p: Vec3) -> bool {
    let q = leaf.csg_from_leaf.inverse().transform_point3(p);
    match &leaf.shape {
        Shape::Sphere { radius } => q.length_squared() < radius * radius,
        Shape::Box { half_extents } => q.abs().cmplt(*half_extents).all(),
        Shape::Cylinder { radius, height } => {
            q.y.abs() < height / 2.0 && q.x * q.x + q.z * q.z < radius * radius
        }
        Shape::Cone { radius, height } => {
            let r = radius * (height - q.y) / height;
            q.y > 0.0 && q.y < *height && q.x * q.x + q.z * q.z < r * r
        }
        Shape::Mesh(mesh) => mesh_contains(mesh, q),
        Shape::Plane(_) | Shape::Csg(_) => false,
    }
}

/// Parity of the crossings of the ray from `q` along a slightly tilted +x
/// (tilted so that it rarely passes exactly through an edge).
fn mesh_contains(mesh: &Mesh, q: Vec3) -> bool {
    let d = Vec3::new(1.0, 1.3e-3, 0.7e-3);
    let mut crossings = 0;
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
        let (e1, e2) = (b - a, c - a);
        let pv = d.cross(e2);
        let det = e1.dot(pv);
        if det.abs() < 1e-12 {
            continue;
        }
        let tv = q - a;
        let u = tv.dot(pv) / det;
        let qv = tv.cross(e1);
        let v = d.dot(qv) / det;
        let s = e2.dot(qv) / det;
        if (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && s > 0.0 {
            crossings += 1;
        }
    }
    crossings % 2 == 1
}

impl Csg {
    /// Object-space bounds (a conservative box).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let (lo, hi) = self.root.bounds();
        if lo.cmple(hi).all() {
            (lo, hi)
        } else {
            // Provably empty: a tiny box at the origin keeps the BVH finite.
            (Vec3::ZERO, Vec3::ZERO)
        }
    }

    /// A sphere around the solid in object space, `[x, y, z, radius]`, with
    /// room to spare: the tighter of the tree's own sphere and the sphere
    /// around [`Csg::bounds`], 0.1% wider (plus 1e-6 of its distance from
    /// the origin) so that rounding in a ray's test against it can never
    /// miss a ray that meets the solid. A ray that misses it meets no leaf
    /// of the solid's positive part, so its intervals are empty: the
    /// renderer skips evaluating the tree for it (`GpuShape::params`).
    pub fn bounding_sphere(&self) -> [f32; 4] {
        let (mut c, mut r) = self.root.bounding_sphere();
        let (lo, hi) = self.root.bounds();
        if lo.cmple(hi).all() {
            let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
            let half_diagonal = (hi - lo).length() / 2.0;
            if half_diagonal < r {
                (c, r) = ((lo + hi) / 2.0, half_diagonal);
            }
        }
        let r = r * 1.001 + 1e-6 * (c.length() + r);
        [c.x as f32, c.y as f32, c.z as f32, r as f32]
    }

    /// Checks leaves (sizes, transforms, closed meshes, no planes), empty
    /// unions and intersections, and the interval and stack bounds.
    pub fn check(&self) -> Result<(), String> {
        check_node(&self.root, "CSG root")?;
        let bound = self.root.interval_bound();
        if bound > CSG_MAX_INTERVALS {
            return Err(format!(
                "CSG tree too complex: a ray may meet up to {bound} separate intervals of it, \
                 over the limit of {CSG_MAX_INTERVALS} (convex leaves count 1, mesh leaves {}, \
                 Union sums, Intersection sums minus (children - 1), Difference sums); \
                 split it into several shapes",
                CSG_MESH_MAX_CROSSINGS / 2
            ));
        }
        let need = self.root.stack_need();
        if need > CSG_STACK {
            return Err(format!(
                "CSG tree too deep: evaluating it needs {need} stack entries, over the limit of \
                 {CSG_STACK}; flatten nested operations (Union([a, b, c]) instead of \
                 Union([a, Union([b, c])]))"
            ));
        }
        Ok(())
    }

    /// Checks that leaf material ids are below `material_count`.
    pub fn check_materials(&self, material_count: usize) -> Result<(), String> {
        for leaf in self.root.leaves() {
            if let Some(m) = leaf.material {
                if m >= material_count {
                    return Err(format!(
                        "CSG leaf material id {m} out of range ({material_count} materials)"
                    ));
                }
            }
        }
        Ok(())
    }
}

fn check_node(node: &CsgNode, path: &str) -> Result<(), String> {
    match node {
        CsgNode::Union(c) | CsgNode::Intersection(c) => {
            let op = if matches!(node, CsgNode::Union(_)) {
                "Union"
            } else {
                "Intersection"
            };
            if c.is_empty() {
                return Err(format!(
                    "{path}: {op}([]) is empty; give it at least one solid"
                ));
            }
            for (i, child) in c.iter().enumerate() {
                check_node(child, &format!("{path} > {op} child {i}"))?;
            }
            Ok(())
        }
        CsgNode::Difference(a, b) => {
            check_node(a, &format!("{path} > Difference first"))?;
            check_node(b, &format!("{path} > Difference second"))
        }
        CsgNode::Leaf(leaf) => {
            let kind = leaf.shape.kind_name();
            match &leaf.shape {
                Shape::Plane(_) => {
                    return Err(format!(
                        "{path}: a {kind} has no inside and cannot be a CSG leaf; use a thin Box"
                    ))
                }
                Shape::Csg(_) => return Err(format!("{path}: nested CSG shapes as leaves")),
                Shape::Mesh(mesh) => {
                    if let Err(m) = closed_mesh(mesh) {
                        return Err(format!(
                            "{path}: mesh {} is not closed ({m}); only closed meshes can be CSG leaves",
                            mesh.source
                        ));
                    }
                }
                _ => {}
            }
            leaf.shape
                .validate()
                .map_err(|m| format!("{path} ({kind}): {m}"))?;
            let m = leaf.csg_from_leaf;
            if !m.is_finite() || m.row(3) != glam::Vec4::W {
                return Err(format!(
                    "{path} ({kind}): transform must be finite and affine"
                ));
            }
            if m.determinant().abs() < super::MIN_TRANSFORM_DETERMINANT {
                return Err(format!(
                    "{path} ({kind}): transform is singular (determinant {:e})",
                    m.determinant()
                ));
            }
            Ok(())
        }
    }
}

/// A mesh is closed when, after welding vertices at equal positions, every
/// edge belongs to exactly two triangles that use it in opposite directions.
pub fn closed_mesh(mesh: &Mesh) -> Result<(), String> {
    use std::collections::HashMap;
    let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
    let ids: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let key = p.to_array().map(|c| (c + 0.0).to_bits());
            let next = weld.len() as u32;
            *weld.entry(key).or_insert(next)
        })
        .collect();
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in mesh.indices.chunks_exact(3) {
        let v = [0, 1, 2].map(|k| ids[t[k] as usize]);
        if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
            continue; // degenerate triangle: no area, no edge
        }
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            let e = edges.entry((a.min(b), a.max(b))).or_insert(0);
            *e += if a < b { 1 } else { 1 << 8 };
        }
    }
    let open = edges.values().filter(|&&c| c != 1 + (1 << 8)).count();
    if open > 0 {
        Err(format!(
            "{open} of {} edges are not shared by exactly two opposite-facing triangles",
            edges.len()
        ))
    } else {
        Ok(())
    }
}
