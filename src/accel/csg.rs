//! CSG trees as postfix programs, and their CPU evaluation by intervals: the
//! reference that shaders/lib/csg.wgsl twins (same steps in the same order).
//!
//! A tree is flattened into instructions (`GpuCsgOp`): a leaf pushes the
//! intervals of t where the ray is inside that leaf; a set operation pops two
//! interval lists and pushes their union, intersection or difference. Each
//! list is a sorted run of endpoints (entry, exit, entry, exit, ...) that
//! carry the outward normal of the result there and the leaf's material.
//! The first endpoint in (t_min, t_max) of the final list is the hit.
//!
//! On the GPU, a tree of at most `CSG_FAST_MAX_LEAVES` convex leaves is
//! evaluated another way (`intersect_csg_fast`, lib/csg.wgsl): by its truth
//! table ([`fast_table`]), which classifies each leaf span's ends. It gives
//! the answers of these lists up to what lies within `csg_eps` of an end
//! (tests/csg_gpu.rs compares the two on random trees).
//!
//! Leaves are evaluated over the whole line (t from -1e30 to 1e30), so
//! whether the ray starts inside a leaf never matters; convex analytic leaves
//! reuse the exact intersection functions twice (the entry, then the exit
//! after it); mesh leaves collect every crossing through the mesh's BVH
//! (walked by the one traversal loop, [`super::traverse`]).

use std::ops::ControlFlow;

use glam::{Mat4, Vec3};

use super::layout::{
    BvhNode, GpuCsgLeaf, GpuCsgOp, GpuTriangle, CSG_FAST_COUNT_SHIFT, CSG_FAST_MAX_LEAVES,
    CSG_NO_MATERIAL, CSG_OP_DIFFERENCE, CSG_OP_END, CSG_OP_INTERSECTION, CSG_OP_LEAF, CSG_OP_UNION,
    MAX_TRAVERSAL_STEPS, SHAPE_BOX, SHAPE_CONE, SHAPE_CYLINDER, SHAPE_MESH, SHAPE_SPHERE,
};
use super::{intersect, traverse, AccelError, BoxRay, ChildOrder, Stopped};
use crate::scene::{Csg, CsgNode, Mesh, CSG_MAX_INTERVALS, CSG_MESH_MAX_CROSSINGS, CSG_STACK};

/// Leaves are intersected over (-CSG_FAR, CSG_FAR): the whole line.
pub const CSG_FAR: f32 = 1.0e30;

/// Epsilon strategy (handed to shaders/lib/csg.wgsl by the limits header
/// that `gpu::shader::limits_header` generates).
///
/// Two consecutive endpoints of an interval list closer than
/// `csg_eps(t) = CSG_EPS_ABS + CSG_EPS_REL * |t|` cancel each other: a gap
/// that short between two intervals is closed, an interval that short is
/// dropped. This runs after every leaf and every set operation, so:
/// - coincident surfaces of two leaves (a face cut flush by another solid,
///   two solids touching) differ only by rounding, far below the epsilon,
///   and give the same answer at every pixel: no slivers, no pinholes;
/// - a ray grazing a leaf (tangent to a sphere, along a box edge) gives a
///   vanishing interval, which is dropped, not kept at random.
///
/// Rounding in t through the transforms is ~1e-7 relative, so 1e-5 relative
/// leaves a factor of 100; features thinner than 1e-5 of the distance to
/// the eye (1e-5 absolute near the origin) vanish.
pub const CSG_EPS_ABS: f32 = 1.0e-5;
/// See [`CSG_EPS_ABS`].
pub const CSG_EPS_REL: f32 = 1.0e-5;

/// Endpoints one stack entry holds.
const ENDPOINTS: usize = 2 * CSG_MAX_INTERVALS as usize;

pub fn csg_eps(t: f32) -> f32 {
    CSG_EPS_ABS + CSG_EPS_REL * t.abs()
}

/// One boundary of an interval list.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Endpoint {
    pub t: f32,
    /// Outward normal of the (partial) solid, in CSG object space, not unit.
    pub normal: Vec3,
    /// Leaf material id or `CSG_NO_MATERIAL`.
    pub material: u32,
}

/// Why an evaluation gave up (reported as overflow, never rendered wrong).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CsgOverflow {
    /// More loop iterations than the per-query budget.
    Steps,
    /// A list over `2 * CSG_MAX_INTERVALS` endpoints or a mesh leaf over
    /// `CSG_MESH_MAX_CROSSINGS` crossings.
    Intervals,
}

/// Appends `e`, or cancels it against the last endpoint when the two are
/// closer than [`csg_eps`] (see there).
fn push(list: &mut Vec<Endpoint>, e: Endpoint) -> Result<(), CsgOverflow> {
    if let Some(last) = list.last() {
        if e.t - last.t < csg_eps(e.t) {
            list.pop();
            return Ok(());
        }
    }
    if list.len() >= ENDPOINTS {
        return Err(CsgOverflow::Intervals);
    }
    list.push(e);
    Ok(())
}

/// The leaf kinds whose spans `csg_leaf_span` (lib/csg.wgsl) computes: a
/// tree with another leaf runs on interval lists.
pub const FAST_KINDS: [u32; 4] = [SHAPE_SPHERE, SHAPE_BOX, SHAPE_CYLINDER, SHAPE_CONE];

/// Where [`compile`] put a tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Program {
    /// The index of its first instruction (`GpuShape::blas_root`).
    pub start: u32,
    /// `GpuShape::csg_fast`: its leaf count and first leaf where its
    /// truth table is in its leaves' `table` words ([`fast_table`]), else 0.
    pub fast: u32,
}

/// Flattens `csg` into `ops` (ending with `CSG_OP_END`) and `leaves`; mesh
/// leaves get their bottom-level BVH from `add_mesh` (which returns its
/// root). A tree of at most [`CSG_FAST_MAX_LEAVES`] analytic leaves also
/// gets its truth table ([`fast_table`]) in its leaves' `table` words.
pub fn compile(
    csg: &Csg,
    ops: &mut Vec<GpuCsgOp>,
    leaves: &mut Vec<GpuCsgLeaf>,
    add_mesh: &mut dyn FnMut(&Mesh) -> Result<u32, AccelError>,
) -> Result<Program, AccelError> {
    let start = ops.len() as u32;
    let first = leaves.len() as u32;
    emit(&csg.root, ops, leaves, add_mesh)?;
    ops.push(GpuCsgOp {
        op: CSG_OP_END,
        arg: 0,
    });
    let own = &mut leaves[first as usize..];
    let analytic = own.iter().all(|l| FAST_KINDS.contains(&l.kind));
    let count = own.len() as u32;
    let fast = if analytic && count <= CSG_FAST_MAX_LEAVES && first < 1 << CSG_FAST_COUNT_SHIFT {
        let table = fast_table(&ops[start as usize..], first, count);
        for (leaf, word) in own.iter_mut().zip(table) {
            leaf.table = word;
        }
        count << CSG_FAST_COUNT_SHIFT | first
    } else {
        0
    };
    Ok(Program { start, fast })
}

/// The truth table of a program (`ops`, from its first instruction) whose
/// leaves are `count` leaves from index `first`: bit m (of word m / 32) is
/// set when the solid holds the points inside exactly the leaves whose bits
/// are set in m (bit i: leaf `first + i`). The table words of
/// `intersect_csg_fast` (lib/csg.wgsl), which classifies points along a ray
/// by it instead of running the program on interval lists.
pub fn fast_table(ops: &[GpuCsgOp], first: u32, count: u32) -> Vec<u32> {
    let mut words = vec![0u32; (1usize << count).div_ceil(32)];
    for m in 0..1u32 << count {
        let mut stack: Vec<bool> = Vec::new();
        for op in ops {
            match op.op {
                CSG_OP_END => break,
                CSG_OP_LEAF => stack.push(m >> (op.arg - first) & 1 == 1),
                set => {
                    let (top, below) = (stack.pop(), stack.pop());
                    let (Some(top), Some(below)) = (top, below) else {
                        unreachable!("compile emits well-formed programs")
                    };
                    let (a, b) = if op.arg == 1 {
                        (top, below)
                    } else {
                        (below, top)
                    };
                    stack.push(match set {
                        CSG_OP_UNION => a || b,
                        CSG_OP_INTERSECTION => a && b,
                        _ => a && !b,
                    });
                }
            }
        }
        if stack == [true] {
            words[(m / 32) as usize] |= 1 << (m % 32);
        }
    }
    words
}

fn emit(
    node: &CsgNode,
    ops: &mut Vec<GpuCsgOp>,
    leaves: &mut Vec<GpuCsgLeaf>,
    add_mesh: &mut dyn FnMut(&Mesh) -> Result<u32, AccelError>,
) -> Result<(), AccelError> {
    match node {
        CsgNode::Leaf(leaf) => {
            let (kind, params) = super::shape_params(&leaf.shape);
            let blas_root = match &leaf.shape {
                crate::scene::Shape::Mesh(mesh) => add_mesh(mesh)?,
                _ => 0,
            };
            let m = leaf.csg_from_leaf;
            leaves.push(GpuCsgLeaf {
                leaf_from_csg: m.inverse().to_cols_array_2d(),
                csg_normal_from_leaf: m.inverse().transpose().to_cols_array_2d(),
                params,
                kind,
                blas_root,
                material: leaf.material.map_or(CSG_NO_MATERIAL, |m| m as u32),
                table: 0,
            });
            ops.push(GpuCsgOp {
                op: CSG_OP_LEAF,
                arg: leaves.len() as u32 - 1,
            });
        }
        CsgNode::Union(children) | CsgNode::Intersection(children) => {
            let op = if matches!(node, CsgNode::Union(_)) {
                CSG_OP_UNION
            } else {
                CSG_OP_INTERSECTION
            };
            // Commutative: the child needing the most stack first.
            let mut order: Vec<&CsgNode> = children.iter().collect();
            order.sort_by_key(|c| std::cmp::Reverse(c.stack_need()));
            for (i, child) in order.into_iter().enumerate() {
                emit(child, ops, leaves, add_mesh)?;
                if i > 0 {
                    ops.push(GpuCsgOp { op, arg: 0 });
                }
            }
        }
        CsgNode::Difference(a, b) => {
            let swapped = b.stack_need() > a.stack_need();
            if swapped {
                emit(b, ops, leaves, add_mesh)?;
                emit(a, ops, leaves, add_mesh)?;
            } else {
                emit(a, ops, leaves, add_mesh)?;
                emit(b, ops, leaves, add_mesh)?;
            }
            ops.push(GpuCsgOp {
                op: CSG_OP_DIFFERENCE,
                arg: u32::from(swapped),
            });
        }
    }
    Ok(())
}

/// The data a CSG program reads: its instructions and leaves, and the BVH
/// nodes and triangles of its mesh leaves.
#[derive(Debug, Clone, Copy)]
pub struct CsgData<'a> {
    pub ops: &'a [GpuCsgOp],
    pub leaves: &'a [GpuCsgLeaf],
    pub nodes: &'a [BvhNode],
    pub triangles: &'a [GpuTriangle],
}

/// A single tree compiled on its own (tests and tools): owns its arrays.
#[derive(Debug, Clone)]
pub struct CompiledCsg {
    pub ops: Vec<GpuCsgOp>,
    pub leaves: Vec<GpuCsgLeaf>,
    pub nodes: Vec<BvhNode>,
    pub triangles: Vec<GpuTriangle>,
}

impl CompiledCsg {
    pub fn new(csg: &Csg) -> Result<CompiledCsg, AccelError> {
        let mut nodes = Vec::new();
        let mut triangles = Vec::new();
        let mut ops = Vec::new();
        let mut leaves = Vec::new();
        let mut depth = 0;
        compile(csg, &mut ops, &mut leaves, &mut |mesh| {
            super::append_mesh_blas(mesh, "CSG leaf", &mut nodes, &mut triangles, &mut depth)
        })?;
        Ok(CompiledCsg {
            ops,
            leaves,
            nodes,
            triangles,
        })
    }

    pub fn data(&self) -> CsgData<'_> {
        CsgData {
            ops: &self.ops,
            leaves: &self.leaves,
            nodes: &self.nodes,
            triangles: &self.triangles,
        }
    }

    /// The intervals of the whole line `o + t d` inside the solid.
    pub fn intervals(&self, o: Vec3, d: Vec3) -> Result<Vec<Endpoint>, CsgOverflow> {
        let mut steps = 0;
        intervals(self.data(), 0, o, d, &mut steps)
    }
}

/// Runs the program starting at `start` for the ray (o, d) in CSG object
/// space; `steps` counts loop iterations against MAX_TRAVERSAL_STEPS.
pub fn intervals(
    data: CsgData,
    start: u32,
    o: Vec3,
    d: Vec3,
    steps: &mut u32,
) -> Result<Vec<Endpoint>, CsgOverflow> {
    let mut stack: Vec<Vec<Endpoint>> = Vec::with_capacity(CSG_STACK as usize);
    let mut pc = start as usize;
    loop {
        take_step(steps)?;
        let op = data.ops[pc];
        pc += 1;
        match op.op {
            CSG_OP_END => break,
            CSG_OP_LEAF => {
                if stack.len() >= CSG_STACK as usize {
                    return Err(CsgOverflow::Intervals);
                }
                stack.push(leaf_intervals(
                    data,
                    &data.leaves[op.arg as usize],
                    o,
                    d,
                    steps,
                )?);
            }
            set_op => {
                let (Some(top), Some(below)) = (stack.pop(), stack.pop()) else {
                    return Err(CsgOverflow::Intervals);
                };
                let (a, b) = if op.arg == 1 {
                    (top, below)
                } else {
                    (below, top)
                };
                stack.push(combine(set_op, &a, &b, steps)?);
            }
        }
    }
    match (stack.pop(), stack.is_empty()) {
        (Some(list), true) => Ok(list),
        _ => Err(CsgOverflow::Intervals),
    }
}

fn take_step(steps: &mut u32) -> Result<(), CsgOverflow> {
    *steps += 1;
    if *steps > MAX_TRAVERSAL_STEPS {
        Err(CsgOverflow::Steps)
    } else {
        Ok(())
    }
}

/// The set operation `op` of two endpoint lists, by one sweep over both.
/// Endpoints of a subtracted solid get their normals flipped: its entry is
/// where the result is left, and the outward normal there points into it.
fn combine(
    op: u32,
    a: &[Endpoint],
    b: &[Endpoint],
    steps: &mut u32,
) -> Result<Vec<Endpoint>, CsgOverflow> {
    let mut out = Vec::with_capacity(ENDPOINTS);
    let (mut i, mut j) = (0, 0);
    let (mut in_a, mut in_b) = (false, false);
    while i < a.len() || j < b.len() {
        // Past the end of a, nothing more can be inside an intersection or a
        // difference; past the end of b, nothing more inside an intersection.
        if op != CSG_OP_UNION && i >= a.len() {
            break;
        }
        if op == CSG_OP_INTERSECTION && j >= b.len() {
            break;
        }
        take_step(steps)?;
        let mut e;
        if j >= b.len() || (i < a.len() && a[i].t <= b[j].t) {
            e = a[i];
            i += 1;
            in_a = !in_a;
        } else {
            e = b[j];
            j += 1;
            in_b = !in_b;
            if op == CSG_OP_DIFFERENCE {
                e.normal = -e.normal;
            }
        }
        let inside = match op {
            CSG_OP_UNION => in_a || in_b,
            CSG_OP_INTERSECTION => in_a && in_b,
            _ => in_a && !in_b,
        };
        if inside != (out.len() % 2 == 1) {
            push(&mut out, e)?;
        }
    }
    Ok(out)
}

fn leaf_intervals(
    data: CsgData,
    leaf: &GpuCsgLeaf,
    o: Vec3,
    d: Vec3,
    steps: &mut u32,
) -> Result<Vec<Endpoint>, CsgOverflow> {
    let m = Mat4::from_cols_array_2d(&leaf.leaf_from_csg);
    let nm = Mat4::from_cols_array_2d(&leaf.csg_normal_from_leaf);
    let lo = m.transform_point3(o);
    let ld = m.transform_vector3(d);
    let mut out = Vec::with_capacity(ENDPOINTS);
    if leaf.kind == SHAPE_MESH {
        for (t, n) in mesh_crossings(data, leaf.blas_root, lo, ld, steps)? {
            push(
                &mut out,
                Endpoint {
                    t,
                    normal: nm.transform_vector3(n),
                    material: leaf.material,
                },
            )?;
        }
        return Ok(out);
    }
    let Some(entry) = intersect::analytic(leaf.kind, leaf.params, lo, ld, -CSG_FAR, CSG_FAR) else {
        return Ok(out);
    };
    let Some(exit) = intersect::analytic(leaf.kind, leaf.params, lo, ld, entry.t, CSG_FAR) else {
        return Ok(out);
    };
    for h in [entry, exit] {
        push(
            &mut out,
            Endpoint {
                t: h.t,
                normal: nm.transform_vector3(h.normal),
                material: leaf.material,
            },
        )?;
    }
    Ok(out)
}

/// Every crossing of the line (o, d) with the mesh, sorted by t, reduced to
/// alternating entries and exits: a crossing is an entry when the ray runs
/// against the triangle's geometric normal; an entry while already inside or
/// an exit while outside (the same crossing found twice, on a shared edge)
/// is skipped. At most CSG_MESH_MAX_CROSSINGS raw crossings are kept; more
/// is an overflow.
fn mesh_crossings(
    data: CsgData,
    root: u32,
    o: Vec3,
    d: Vec3,
    steps: &mut u32,
) -> Result<Vec<(f32, Vec3)>, CsgOverflow> {
    let mut hits: Vec<(f32, Vec3, bool)> = Vec::new();
    let bounds = &data.nodes[root as usize];
    let ray = intersect::TriangleRay::new(
        o,
        d,
        Vec3::from(bounds.bounds_min),
        Vec3::from(bounds.bounds_max),
    );
    let walked = traverse(
        data.nodes,
        root,
        BoxRay::new(o, d, -CSG_FAR),
        CSG_FAR,
        ChildOrder::LeftFirst,
        steps,
        |triangles, _, _| {
            for k in triangles {
                if let Some(h) =
                    intersect::triangle(&ray, &data.triangles[k as usize], -CSG_FAR, CSG_FAR)
                {
                    if hits.len() >= CSG_MESH_MAX_CROSSINGS as usize {
                        return ControlFlow::Break(CsgOverflow::Intervals);
                    }
                    // Insertion sort by t (stable: ties keep discovery order).
                    let at = hits.partition_point(|x| x.0 <= h.t);
                    hits.insert(at, (h.t, h.normal, h.geometric.dot(d) < 0.0));
                }
            }
            ControlFlow::Continue(())
        },
    );
    match walked {
        Ok(()) => {}
        Err(Stopped::Steps) => return Err(CsgOverflow::Steps),
        Err(Stopped::Leaf(overflow)) => return Err(overflow),
    }
    let mut out = Vec::new();
    let mut inside = false;
    for (t, n, entering) in hits {
        if entering != inside {
            out.push((t, n));
            inside = entering;
        }
    }
    if inside {
        out.pop();
    }
    Ok(out)
}

/// Whether the ray (o, d) may meet the solid in (t_min, t_max): its
/// segment there meets the solid's bounding sphere (`bound`, from
/// [`crate::scene::Csg::bounding_sphere`]). The closest point of the line
/// to the centre, not the quadratic's discriminant, so that rounding stays
/// small beside the radius; the reach grows by 1e-5 of the origin's
/// distance for far rays. Twin of `csg_bound_may_hit` (lib/csg.wgsl).
pub fn bound_may_hit(bound: [f32; 4], o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
    let oc = o - Vec3::from_slice(&bound[..3]);
    let dd = d.dot(d);
    let t_mid = -oc.dot(d) / dd;
    let p = oc + d * t_mid;
    let reach = bound[3] + 1e-5 * oc.length();
    let gap = reach * reach - p.dot(p);
    if gap < 0.0 {
        return false;
    }
    let half = (gap / dd).sqrt();
    t_mid + half > t_min && t_mid - half < t_max
}

/// The closest boundary of the program's solid in (t_min, t_max): the CPU
/// twin of `intersect_csg`. Returns the hit and the leaf material, or why
/// the evaluation gave up; `steps` counts loop iterations.
pub fn closest(
    data: CsgData,
    start: u32,
    o: Vec3,
    d: Vec3,
    t_min: f32,
    t_max: f32,
    steps: &mut u32,
) -> Result<Option<(intersect::ObjectHit, u32)>, CsgOverflow> {
    let list = intervals(data, start, o, d, steps)?;
    let Some(e) = list.into_iter().find(|e| e.t > t_min) else {
        return Ok(None);
    };
    Ok((e.t < t_max).then_some((
        intersect::ObjectHit {
            t: e.t,
            normal: e.normal,
            geometric: e.normal,
        },
        e.material,
    )))
}
