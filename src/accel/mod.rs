//! Acceleration structures for the ray tracer, built on the CPU: a bottom-level
//! BVH per mesh (binned SAH over triangles; an analytic shape is its own
//! leaf) and a top-level BVH over instances (world bounds of each transformed
//! bottom level). Also the CPU reference traversal the tests compare the GPU
//! against (one stack loop, [`traverse`], walks the top level, the meshes'
//! bottom levels and CSG mesh leaves); it is never used for rendering.
//! Imports scene and glam; the plain Pod layouts it builds for the GPU are
//! in [`layout`] (no GPU types here).

pub mod bvh;
pub mod csg;
pub mod intersect;
pub mod layout;
pub mod screen_tiles;
pub mod shadow_cull;

use std::ops::ControlFlow;

use glam::{Mat4, Vec3};

use crate::scene::{
    Mesh, PlaneKind, Scene, Shape, CSG_MAX_INTERVALS, CSG_MESH_MAX_CROSSINGS, CSG_STACK,
};
use bvh::Aabb;
use layout::{
    BvhNode, GpuCsgLeaf, GpuCsgOp, GpuShape, GpuTriangle, CSG_NO_MATERIAL, CSG_OP_END,
    CSG_OP_INTERSECTION, CSG_OP_LEAF, MAX_TRAVERSAL_STEPS, SHAPE_BOX, SHAPE_CONE, SHAPE_CSG,
    SHAPE_CYLINDER, SHAPE_DISK, SHAPE_MESH, SHAPE_QUAD, SHAPE_SPHERE, TRAVERSAL_STACK,
};
use screen_tiles::Footprint;

/// Triangles per bottom-level leaf and instances per top-level leaf.
const MESH_LEAF: usize = 4;
const INSTANCE_LEAF: usize = 2;

#[derive(Debug, thiserror::Error)]
pub enum AccelError {
    #[error(
        "shape '{shape}': its BVH is {depth} levels deep, over the traversal stack of {limit}"
    )]
    TooDeep {
        shape: String,
        depth: u32,
        limit: u32,
    },
}

/// How long the kernels' private arrays must be for a scene, each at most
/// its full length ([`PrivateSizes::FULL`], the limits scenes are checked
/// against at load). lavapipe zero-fills a private array at each
/// invocation's start and indexes it the slower the longer it is, so the
/// trace kernels are built with these lengths (`gpu::shader::
/// create_module_sized`); no walk or CSG evaluation of the scene can
/// reach their ends, so the images are those of the full lengths.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PrivateSizes {
    /// Traversal stack entries (`TRACE_STACK`): the top level's depth plus
    /// the deepest bottom level's (a mesh's, or a CSG mesh leaf's), since
    /// a walk holds at most one entry per inner node on its path, and a
    /// bottom-level walk continues above its top-level walk's entries.
    pub trace_stack: u32,
    /// CSG evaluator stack entries (`CSG_EVAL_STACK`): the most any of the
    /// scene's CSG programs pushes.
    pub csg_stack: u32,
    /// Intervals a CSG stack entry holds (`CSG_EVAL_INTERVALS`): the most
    /// any entry of the scene's programs can hold for any ray, by the
    /// bounds `scene::csg` checks trees against.
    pub csg_intervals: u32,
}

impl Default for PrivateSizes {
    fn default() -> Self {
        PrivateSizes::FULL
    }
}

impl PrivateSizes {
    /// The full lengths: what any scene that loads fits.
    pub const FULL: PrivateSizes = PrivateSizes {
        trace_stack: TRAVERSAL_STACK,
        csg_stack: CSG_STACK,
        csg_intervals: CSG_MAX_INTERVALS,
    };

    /// The sizes for a traversal stack of `trace_stack` entries and the
    /// CSG programs in `ops` (each ending with `CSG_OP_END`) over
    /// `leaves`, whose lengths come from running them on bounds: a leaf
    /// pushes 1 interval (CSG_MESH_MAX_CROSSINGS / 2 for a mesh leaf), a
    /// union the sum of its operands', an intersection the sum less 1, a
    /// difference the sum. At least 1 each (a scene without CSG), at most
    /// the full lengths.
    pub fn new(trace_stack: u32, ops: &[GpuCsgOp], leaves: &[GpuCsgLeaf]) -> PrivateSizes {
        let (mut stack, mut most_stack, mut most_intervals) = (Vec::new(), 1, 1);
        for op in ops {
            match op.op {
                CSG_OP_END => stack.clear(),
                CSG_OP_LEAF => {
                    let mesh = leaves[op.arg as usize].kind == SHAPE_MESH;
                    stack.push(if mesh { CSG_MESH_MAX_CROSSINGS / 2 } else { 1 });
                }
                set => {
                    let (b, a) = (stack.pop().unwrap_or(1), stack.pop().unwrap_or(1));
                    let sum = a + b;
                    stack.push(if set == CSG_OP_INTERSECTION {
                        (sum - 1).max(1)
                    } else {
                        sum
                    });
                }
            }
            most_stack = most_stack.max(stack.len() as u32);
            most_intervals = most_intervals.max(stack.last().copied().unwrap_or(1));
        }
        PrivateSizes {
            trace_stack: trace_stack.clamp(1, TRAVERSAL_STACK),
            csg_stack: most_stack.min(CSG_STACK),
            csg_intervals: most_intervals.min(CSG_MAX_INTERVALS),
        }
    }
}

/// Everything the trace pass reads, as flat arrays.
#[derive(Debug, Clone)]
pub struct SceneAccel {
    pub shapes: Vec<GpuShape>,
    /// Top level at 0 (root 0), then every mesh's bottom level.
    pub nodes: Vec<BvhNode>,
    /// How many of `nodes` are the top level's.
    pub top_nodes: usize,
    pub triangles: Vec<GpuTriangle>,
    /// Top-level leaf slots -> GPU instance index.
    pub tlas_items: Vec<u32>,
    /// Per GPU instance: (world_from_object, object_from_world, shape).
    pub instances: Vec<(Mat4, Mat4, u32)>,
    /// Per GPU instance: its world box over the whole shutter (the top
    /// level's leaf boxes), and whether it moves.
    pub world_bounds: Vec<Aabb>,
    pub moving: Vec<bool>,
    /// Per GPU instance, what the screen tiles project
    /// (`screen_tiles::Footprint`): its world box and, for static spheres
    /// and CSG solids, a world sphere holding it ([`world_sphere`]).
    pub footprints: Vec<Footprint>,
    /// The instances that are exactly spheres (`exact_spheres`), for the
    /// outline tiles the CPU proves smooth
    /// (`screen_tiles::smooth_sphere_tiles`).
    pub exact_spheres: Vec<screen_tiles::ExactSphere>,
    /// The static quads and disks (`exact_planes`), for the same proof
    /// (`screen_tiles::smooth_plane_tiles`).
    pub exact_planes: Vec<screen_tiles::ExactPlane>,
    /// Postfix programs of the CSG shapes (each ends with CSG_OP_END).
    pub csg_ops: Vec<GpuCsgOp>,
    pub csg_leaves: Vec<GpuCsgLeaf>,
    /// Per triangle: (shape id, the mesh vertex of its first corner), or
    /// (u32::MAX, 0) for CSG leaves: where its base-colour map comes from.
    pub triangle_sources: Vec<(u32, u32)>,
    /// The lengths of the private arrays the trace kernels need for this
    /// scene ([`PrivateSizes::new`], from the depths this build measures
    /// and its CSG programs).
    pub sizes: PrivateSizes,
    pub build_ms: f64,
}

/// An upper bound on the square of the largest factor by which `m`
/// stretches a vector: the largest eigenvalue of mᵀm, bounded by
/// Gershgorin's circle theorem (its largest absolute row sum; exact for
/// rotations with uniform scale).
pub fn squared_stretch_bound(m: glam::Mat3) -> f32 {
    // Symmetric: its columns are its rows.
    let gram = m.transpose() * m;
    [gram.x_axis, gram.y_axis, gram.z_axis]
        .map(|r| r.abs().element_sum())
        .into_iter()
        .fold(0.0, f32::max)
}

/// A world sphere (centre xyz, radius w) holding an instance of `shape`
/// placed by `world_from_object`: for spheres their own, for CSG solids
/// their bounding sphere (`Csg::bounding_sphere`), the radius scaled by
/// the matrix's largest stretch ([`squared_stretch_bound`]); none for
/// other shapes.
pub fn world_sphere(shape: &GpuShape, world_from_object: Mat4) -> Option<glam::Vec4> {
    let (centre, radius) = match shape.kind {
        SHAPE_SPHERE => (Vec3::ZERO, shape.params[0]),
        SHAPE_CSG => (Vec3::from_slice(&shape.params[..3]), shape.params[3]),
        _ => return None,
    };
    let stretch = squared_stretch_bound(glam::Mat3::from_mat4(world_from_object)).sqrt();
    Some(
        world_from_object
            .transform_point3(centre)
            .extend(radius * stretch),
    )
}

/// Eight points, in order around it, of a flat convex polygon holding an
/// instance of a quad or disk placed by `world_from_object`: a quad's
/// corners and the middles of its sides, or the octagon around a disk
/// (its corners at radius / cos 22.5 degrees); none for other shapes.
pub fn world_outline(shape: &GpuShape, world_from_object: Mat4) -> Option<[Vec3; 8]> {
    let disk = match shape.kind {
        SHAPE_QUAD => false,
        SHAPE_DISK => true,
        _ => return None,
    };
    let p = shape.params;
    Some(std::array::from_fn(|i| {
        let a = i as f32 * std::f32::consts::FRAC_PI_4;
        let (x, z) = if disk {
            let r = p[0] / std::f32::consts::FRAC_PI_8.cos();
            (r * a.cos(), r * a.sin())
        } else {
            // The unit square's corners and middles, scaled.
            let (c, s) = (a.cos(), a.sin());
            let m = c.abs().max(s.abs());
            (p[0] * c / m, p[1] * s / m)
        };
        world_from_object.transform_point3(Vec3::new(x, 0.0, z))
    }))
}

/// The instances that are exactly spheres in the world
/// (`screen_tiles::ExactSphere`): static spheres (those whose footprint
/// has a [`world_sphere`]) whose matrix is a similarity (columns of one
/// length and at right angles, to a relative 1e-5), so that their world
/// sphere is the surface itself and every hit the kernels find on them
/// is a hit on it, up to f32 rounding.
fn exact_spheres(
    shapes: &[GpuShape],
    instances: &[(Mat4, Mat4, u32)],
    footprints: &[Footprint],
) -> Vec<screen_tiles::ExactSphere> {
    instances
        .iter()
        .zip(footprints)
        .enumerate()
        .filter(|(_, (&(_, _, shape), _))| shapes[shape as usize].kind == SHAPE_SPHERE)
        .filter_map(|(k, (&(world_from_object, _, _), footprint))| {
            let sphere = footprint.sphere?;
            let m = glam::Mat3::from_mat4(world_from_object);
            let cols = [m.x_axis, m.y_axis, m.z_axis];
            let scale2 = m.x_axis.length_squared();
            let tol = 1e-5 * scale2;
            let similar = (0..3).all(|a| {
                (cols[a].length_squared() - scale2).abs() <= tol
                    && cols[a].dot(cols[(a + 1) % 3]).abs() <= tol
            });
            (similar && scale2 > 0.0).then(|| screen_tiles::ExactSphere {
                instance: k,
                centre: sphere.truncate(),
                radius: sphere.w,
            })
        })
        .collect()
}

/// The flat quads and disks of the static instances
/// (`screen_tiles::ExactPlane`): quads, disks and the six faces of boxes.
/// Every hit the kernels find on them lies on one world plane, whatever
/// their (invertible, affine) matrix: a box's face is where the box test
/// enters through it, its normal the face's (`box_normal` in
/// intersect.wgsl picks the axis the hit lies farthest along, the face's
/// own inside its outline).
fn exact_planes(
    shapes: &[GpuShape],
    instances: &[(Mat4, Mat4, u32)],
    moving: &[bool],
) -> Vec<screen_tiles::ExactPlane> {
    let mut planes = Vec::new();
    for (k, &(_, object_from_world, shape)) in instances.iter().enumerate() {
        if moving[k] {
            continue;
        }
        let shape = &shapes[shape as usize];
        let p = shape.params;
        let plane = |object_from_world, half: glam::Vec2, disk, face| screen_tiles::ExactPlane {
            instance: k,
            object_from_world,
            half,
            disk,
            face,
        };
        match shape.kind {
            SHAPE_QUAD => planes.push(plane(
                object_from_world,
                glam::Vec2::new(p[0], p[1]),
                false,
                false,
            )),
            SHAPE_DISK => planes.push(plane(
                object_from_world,
                glam::Vec2::splat(p[0]),
                true,
                false,
            )),
            SHAPE_BOX => {
                // The face at x_a = s h_a, in the frame (x_b, s x_a - h_a,
                // x_c), the other two axes across it.
                for a in 0..3 {
                    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
                    for s in [1.0f32, -1.0] {
                        // Its columns: where the object's axes go.
                        let mut cols = [glam::Vec4::ZERO; 4];
                        cols[a] = glam::Vec4::Y * s;
                        cols[b] = glam::Vec4::X;
                        cols[c] = glam::Vec4::Z;
                        cols[3] = glam::Vec4::new(0.0, -p[a], 0.0, 1.0);
                        let face_from_object = Mat4::from_cols(cols[0], cols[1], cols[2], cols[3]);
                        let frame = face_from_object * object_from_world;
                        planes.push(plane(frame, glam::Vec2::new(p[b], p[c]), false, true));
                    }
                }
            }
            _ => {}
        }
    }
    planes
}

/// Builds a mesh's bottom-level BVH, appending its nodes (child indices
/// relative to `nodes`) and triangles; returns its root node index.
pub(crate) fn append_mesh_blas(
    mesh: &Mesh,
    name: &str,
    nodes: &mut Vec<BvhNode>,
    triangles: &mut Vec<GpuTriangle>,
    max_depth: &mut u32,
) -> Result<u32, AccelError> {
    append_mesh_blas_with_sources(mesh, name, nodes, triangles, max_depth, &mut Vec::new())
}

/// [`append_mesh_blas`], also appending each triangle's first corner's
/// vertex index to `first_corners`.
fn append_mesh_blas_with_sources(
    mesh: &Mesh,
    name: &str,
    nodes: &mut Vec<BvhNode>,
    triangles: &mut Vec<GpuTriangle>,
    max_depth: &mut u32,
    first_corners: &mut Vec<u32>,
) -> Result<u32, AccelError> {
    let tri_bounds: Vec<Aabb> = mesh
        .indices
        .chunks_exact(3)
        .map(|t| {
            t.iter().fold(Aabb::EMPTY, |b, &i| {
                b.grow_point(mesh.positions[i as usize])
            })
        })
        .collect();
    let blas = bvh::build(&tri_bounds, MESH_LEAF);
    *max_depth = (*max_depth).max(blas.depth);
    if blas.depth > TRAVERSAL_STACK / 2 {
        return Err(AccelError::TooDeep {
            shape: name.to_string(),
            depth: blas.depth,
            limit: TRAVERSAL_STACK / 2,
        });
    }
    let node_base = nodes.len() as u32;
    let tri_base = triangles.len() as u32;
    for &item in &blas.items {
        let t = &mesh.indices[item as usize * 3..item as usize * 3 + 3];
        first_corners.push(t[0]);
        let uv = |k: usize| mesh.uvs.get(t[k] as usize).copied().unwrap_or_default();
        let p = |k: usize| mesh.positions[t[k] as usize].extend(uv(k).x).to_array();
        let n = |k: usize| mesh.normals[t[k] as usize].extend(uv(k).y).to_array();
        triangles.push(GpuTriangle {
            p0: p(0),
            p1: p(1),
            p2: p(2),
            n0: n(0),
            n1: n(1),
            n2: n(2),
        });
    }
    nodes.extend(blas.nodes.iter().map(|n| {
        let mut n = *n;
        n.left_or_first += if n.count > 0 { tri_base } else { node_base };
        n
    }));
    Ok(node_base)
}

pub(crate) fn shape_params(shape: &Shape) -> (u32, [f32; 4]) {
    match shape {
        Shape::Sphere { radius } => (SHAPE_SPHERE, [*radius, 0.0, 0.0, 0.0]),
        Shape::Box { half_extents: h } => (SHAPE_BOX, [h.x, h.y, h.z, 0.0]),
        Shape::Cylinder { radius, height } => (SHAPE_CYLINDER, [*radius, *height, 0.0, 0.0]),
        Shape::Cone { radius, height } => (SHAPE_CONE, [*radius, *height, 0.0, 0.0]),
        Shape::Plane(PlaneKind::Quad { half_size }) => {
            (SHAPE_QUAD, [half_size.x, half_size.y, 0.0, 0.0])
        }
        Shape::Plane(PlaneKind::Disk { radius }) => (SHAPE_DISK, [*radius, 0.0, 0.0, 0.0]),
        Shape::Mesh(_) => (SHAPE_MESH, [0.0; 4]),
        Shape::Csg(csg) => (SHAPE_CSG, csg.bounding_sphere()),
    }
}

impl SceneAccel {
    /// Builds both levels. `instance_order[i]` is the scene instance that is
    /// GPU instance i (the raster pass's shape-sorted order).
    pub fn build(scene: &Scene, instance_order: &[usize]) -> Result<SceneAccel, AccelError> {
        let start = std::time::Instant::now();
        let mut nodes = vec![bytemuck::Zeroable::zeroed()]; // slot 0: TLAS root, filled below
        let mut triangles = Vec::new();
        let mut shapes = Vec::new();
        let mut object_bounds = Vec::new();
        let mut csg_ops = Vec::new();
        let mut csg_leaves = Vec::new();
        let mut max_blas_depth = 0;
        let mut triangle_sources = Vec::new();
        // A shape no instance shows keeps its slot (instances name shapes
        // by index) but gets no bottom level or CSG program: no ray can
        // reach one, so it would only lengthen the buffers and the
        // kernels' private arrays.
        let used = scene.shapes_shown();
        for (id, shape) in scene.shapes.iter().enumerate() {
            let (kind, params) = shape_params(shape);
            let mut gpu_shape = GpuShape {
                params,
                kind,
                blas_root: 0,
                csg_fast: 0,
                _pad1: 0,
            };
            let (lo, hi) = shape.bounds();
            // Planes are flat: pad so slab tests never divide a zero-thick box.
            let pad = Vec3::splat(1e-4 * (hi - lo).max_element().max(1e-3));
            object_bounds.push(Aabb {
                min: lo - pad,
                max: hi + pad,
            });
            let name = scene.shape_names.get(id).cloned().unwrap_or_default();
            if !used[id] {
                shapes.push(gpu_shape);
                continue;
            }
            if let Shape::Mesh(mesh) = shape {
                let mut corners = Vec::new();
                gpu_shape.blas_root = append_mesh_blas_with_sources(
                    mesh,
                    &name,
                    &mut nodes,
                    &mut triangles,
                    &mut max_blas_depth,
                    &mut corners,
                )?;
                triangle_sources.extend(corners.into_iter().map(|v| (id as u32, v)));
            }
            if let Shape::Csg(tree) = shape {
                let program = csg::compile(tree, &mut csg_ops, &mut csg_leaves, &mut |m| {
                    append_mesh_blas(m, &name, &mut nodes, &mut triangles, &mut max_blas_depth)
                })?;
                gpu_shape.blas_root = program.start;
                gpu_shape.csg_fast = program.fast;
            }
            shapes.push(gpu_shape);
            triangle_sources.resize(triangles.len(), (u32::MAX, 0));
        }

        let instances: Vec<(Mat4, Mat4, u32)> = instance_order
            .iter()
            .map(|&i| {
                let inst = &scene.instances[i];
                (
                    inst.world_from_object,
                    inst.world_from_object.inverse(),
                    inst.shape as u32,
                )
            })
            .collect();
        // A moving instance's box covers its whole motion over the shutter:
        // the union of 16 steps, padded by 1% of its diagonal for the arcs a
        // rotation sweeps between steps.
        let world_bounds: Vec<Aabb> = instance_order
            .iter()
            .map(|&i| {
                let inst = &scene.instances[i];
                let local = object_bounds[inst.shape];
                if inst.world_from_object_end.is_none() {
                    return local.transformed(inst.world_from_object);
                }
                let swept = (0..=16)
                    .map(|k| local.transformed(inst.world_from_object_at(k as f32 / 16.0)))
                    .fold(Aabb::EMPTY, Aabb::grow);
                let pad = Vec3::splat((swept.max - swept.min).length() * 0.01);
                Aabb {
                    min: swept.min - pad,
                    max: swept.max + pad,
                }
            })
            .collect();
        let moving: Vec<bool> = instance_order
            .iter()
            .map(|&i| scene.instances[i].world_from_object_end.is_some())
            .collect();
        // A moving instance keeps its box, which covers its motion.
        let footprints = (0..instances.len())
            .map(|k| {
                let (world_from_object, _, shape) = instances[k];
                let shape = &shapes[shape as usize];
                let sphere = world_sphere(shape, world_from_object);
                Footprint {
                    bounds: world_bounds[k],
                    sphere: sphere.filter(|_| !moving[k]),
                    outline: world_outline(shape, world_from_object).filter(|_| !moving[k]),
                }
            })
            .collect::<Vec<_>>();
        let exact_spheres = exact_spheres(&shapes, &instances, &footprints);
        let exact_planes = exact_planes(&shapes, &instances, &moving);
        let tlas = bvh::build(&world_bounds, INSTANCE_LEAF);
        // One stack serves both levels, holding at most one entry per level
        // of the top-level path plus one per level of a mesh's path.
        if tlas.depth + max_blas_depth > TRAVERSAL_STACK {
            return Err(AccelError::TooDeep {
                shape: "(top level + deepest mesh)".into(),
                depth: tlas.depth + max_blas_depth,
                limit: TRAVERSAL_STACK,
            });
        }
        // The TLAS goes first so its root is node 0; shift the BLAS indices.
        let shift = tlas.nodes.len() as u32 - 1;
        for node in nodes.iter_mut().skip(1) {
            if node.count == 0 {
                node.left_or_first += shift;
            }
        }
        // An unused mesh has no bottom level: its root stays 0, which no
        // ray reaches (no instance shows it).
        for (s, used) in shapes.iter_mut().zip(&used) {
            if s.kind == SHAPE_MESH && *used {
                s.blas_root += shift;
            }
        }
        for leaf in &mut csg_leaves {
            if leaf.kind == SHAPE_MESH {
                leaf.blas_root += shift;
            }
        }
        let blas_nodes = nodes.split_off(1);
        let top_nodes = tlas.nodes.len();
        let mut all = tlas.nodes;
        all.extend(blas_nodes);
        let build_ms = start.elapsed().as_secs_f64() * 1e3;
        let sizes = PrivateSizes::new(tlas.depth + max_blas_depth, &csg_ops, &csg_leaves);
        log::info!(
            "BVH build: {} shapes, {} triangles, {} instances, {} nodes, top depth {}, \
             {sizes:?}, {build_ms:.1} ms",
            shapes.len(),
            triangles.len(),
            instances.len(),
            all.len(),
            tlas.depth,
        );
        Ok(SceneAccel {
            shapes,
            nodes: all,
            top_nodes,
            triangles,
            tlas_items: tlas.items,
            instances,
            world_bounds,
            moving,
            footprints,
            exact_spheres,
            exact_planes,
            csg_ops,
            triangle_sources,
            csg_leaves,
            sizes,
            build_ms,
        })
    }

    /// CPU reference: the closest hit of the world ray (origin, dir) in
    /// (t_min, t_max), by the same traversal the GPU runs.
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> TraceResult {
        let mut hit = None;
        let mut steps = 0;
        let ray = BoxRay::new(origin, dir, t_min);
        let walked = traverse(
            &self.nodes,
            0,
            ray,
            t_max,
            ChildOrder::NearerFirst,
            &mut steps,
            |slots, steps, t_best| {
                for slot in slots {
                    let instance = self.tlas_items[slot as usize];
                    let (world_from_object, object_from_world, shape) =
                        self.instances[instance as usize];
                    let o = object_from_world.transform_point3(origin);
                    let d = object_from_world.transform_vector3(dir);
                    let (found, overflow) =
                        self.intersect_shape(shape, o, d, t_min, *t_best, steps);
                    if let Some((h, material)) = found {
                        *t_best = h.t;
                        let to_world = world_from_object.inverse().transpose();
                        hit = Some(Hit {
                            t: h.t,
                            instance,
                            normal: to_world.transform_vector3(h.normal).normalize(),
                            geometric: to_world.transform_vector3(h.geometric).normalize(),
                            leaf_material: (material != CSG_NO_MATERIAL).then_some(material),
                        });
                    }
                    if overflow {
                        return ControlFlow::Break(());
                    }
                }
                ControlFlow::Continue(())
            },
        );
        TraceResult {
            hit,
            steps,
            overflow: walked.is_err(),
        }
    }

    /// The closest hit of the object-space ray (o, d) with `shape` in
    /// (t_min, t_max) and its leaf material, counting loop iterations in
    /// `steps`; true when the query ran out of steps or CSG intervals (the
    /// hit is then the best found before).
    fn intersect_shape(
        &self,
        shape: u32,
        o: Vec3,
        d: Vec3,
        t_min: f32,
        t_max: f32,
        steps: &mut u32,
    ) -> (Option<(intersect::ObjectHit, u32)>, bool) {
        let s = self.shapes[shape as usize];
        if s.kind == SHAPE_CSG {
            // Rays that miss the solid's bounding sphere skip the evaluation.
            if !csg::bound_may_hit(s.params, o, d, t_min, t_max) {
                return (None, false);
            }
            let data = csg::CsgData {
                ops: &self.csg_ops,
                leaves: &self.csg_leaves,
                nodes: &self.nodes,
                triangles: &self.triangles,
            };
            return match csg::closest(data, s.blas_root, o, d, t_min, t_max, steps) {
                Ok(found) => (found, false),
                Err(_) => (None, true),
            };
        }
        if s.kind != SHAPE_MESH {
            let found = intersect::analytic(s.kind, s.params, o, d, t_min, t_max);
            return (found.map(|h| (h, CSG_NO_MATERIAL)), false);
        }
        let mut best: Option<intersect::ObjectHit> = None;
        let root = &self.nodes[s.blas_root as usize];
        let ray = intersect::TriangleRay::new(
            o,
            d,
            Vec3::from(root.bounds_min),
            Vec3::from(root.bounds_max),
        );
        let walked = traverse(
            &self.nodes,
            s.blas_root,
            BoxRay::new(o, d, t_min),
            t_max,
            ChildOrder::NearerFirst,
            steps,
            |triangles, _, t_best| {
                for k in triangles {
                    if let Some(h) =
                        intersect::triangle(&ray, &self.triangles[k as usize], t_min, *t_best)
                    {
                        *t_best = h.t;
                        best = Some(h);
                    }
                }
                ControlFlow::<()>::Continue(())
            },
        );
        (best.map(|h| (h, CSG_NO_MATERIAL)), walked.is_err())
    }
}

/// A ray as the box tests of a traversal see it: origin, reciprocal
/// direction and the near end of the interval searched.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BoxRay {
    pub origin: Vec3,
    pub inv_dir: Vec3,
    pub t_min: f32,
}

impl BoxRay {
    pub(crate) fn new(origin: Vec3, dir: Vec3, t_min: f32) -> BoxRay {
        BoxRay {
            origin,
            inv_dir: dir.recip(),
            t_min,
        }
    }
}

/// Which child of an inner node a traversal visits first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ChildOrder {
    /// The child whose box the ray enters first (closest-hit queries: a
    /// near hit shrinks the interval before the far child is tested).
    NearerFirst,
    /// Always the left child (queries that collect every crossing).
    LeftFirst,
}

/// Why [`traverse`] stopped before visiting every node it had to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stopped<B> {
    /// More loop iterations than MAX_TRAVERSAL_STEPS.
    Steps,
    /// The leaf action broke off with this value.
    Leaf(B),
}

/// The one BVH stack traversal of the CPU reference (the shaders' loop
/// finds the same hits, but tests both children's boxes before pushing
/// them, so its step counts differ): from `root`, pop a node, count one step in `steps`
/// (giving up past MAX_TRAVERSAL_STEPS), skip it when the ray misses its
/// box in (t_min, t_max), push an inner node's two children in `order`
/// (children the ray misses are still pushed; the pop tests them), and hand
/// a leaf's item range to `leaf`. `leaf` gets the step counter (for nested
/// traversals sharing the budget) and t_max, which it lowers when it finds
/// a closer hit; it may break off the traversal.
pub(crate) fn traverse<B>(
    nodes: &[BvhNode],
    root: u32,
    ray: BoxRay,
    t_max: f32,
    order: ChildOrder,
    steps: &mut u32,
    mut leaf: impl FnMut(std::ops::Range<u32>, &mut u32, &mut f32) -> ControlFlow<B>,
) -> Result<(), Stopped<B>> {
    let mut t_max = t_max;
    let mut stack = Vec::with_capacity(TRAVERSAL_STACK as usize);
    stack.push(root);
    while let Some(index) = stack.pop() {
        *steps += 1;
        if *steps > MAX_TRAVERSAL_STEPS {
            return Err(Stopped::Steps);
        }
        let node = nodes[index as usize];
        let b = node.aabb();
        if intersect::ray_box(ray.origin, ray.inv_dir, b.min, b.max, ray.t_min, t_max).is_none() {
            continue;
        }
        if node.count == 0 {
            let left = node.left_or_first;
            let left_first = match order {
                ChildOrder::LeftFirst => true,
                ChildOrder::NearerFirst => {
                    let entry = |i: u32| {
                        let b = nodes[i as usize].aabb();
                        intersect::ray_box(ray.origin, ray.inv_dir, b.min, b.max, 0.0, f32::MAX)
                            .unwrap_or(f32::MAX)
                    };
                    entry(left) <= entry(left + 1)
                }
            };
            // The child visited first is pushed last.
            if left_first {
                stack.push(left + 1);
                stack.push(left);
            } else {
                stack.push(left);
                stack.push(left + 1);
            }
            continue;
        }
        let items = node.left_or_first..node.left_or_first + node.count;
        if let ControlFlow::Break(b) = leaf(items, steps, &mut t_max) {
            return Err(Stopped::Leaf(b));
        }
    }
    Ok(())
}

/// A world-space hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub t: f32,
    /// GPU instance index.
    pub instance: u32,
    /// Unit shading normal (outward, not flipped towards the ray).
    pub normal: Vec3,
    /// Unit geometric normal (outward).
    pub geometric: Vec3,
    /// The material of the CSG leaf hit, when that leaf has one (otherwise
    /// the instance's material applies).
    pub leaf_material: Option<u32>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceResult {
    pub hit: Option<Hit>,
    /// Loop iterations taken (nodes visited at both levels).
    pub steps: u32,
    /// True when the query gave up at MAX_TRAVERSAL_STEPS.
    pub overflow: bool,
}
