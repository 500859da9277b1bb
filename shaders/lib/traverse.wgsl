// Two-level BVH traversal: the WGSL twin of SceneAccel::closest_hit in
// src/accel/mod.rs. It reads the scene's `nodes`, `triangles`, `shapes`,
// `instances` and `tlas_items` (lib/scene_bindings.wgsl).
//
// Lavapipe silently stops an invocation's loops after ~65,535 iterations in
// total. Every traversal step spends one unit of `steps_left`, a budget per
// invocation set well under that; a query that runs out gives up and sets
// `overflowed`, which the pass reports (a visible colour and a counter), so
// a truncated image is never silent.

const NO_HIT: u32 = 0xffffffffu;
// MAX_TRAVERSAL_STEPS and TRACE_STACK: lib/limits.wgsl (generated). TRACE_STACK
// is the stack's length in this module: TRAVERSAL_STACK, or what the
// scene's walks need (src/gpu/shader.rs, create_module_sized).

// False in pipelines for scenes without triangle meshes: the mesh traversal
// is compiled out (the CPU driver runs a smaller kernel faster).
override MESHES_ENABLED: bool = true;
// Scenes of at most a few instances (src/render/scene_buffers.rs,
// FLAT_TOP_LEVEL_MAX): their count, and trace_each tests instances 0 to
// FLAT_TOP_LEVEL - 1 in turn instead of walking the top-level tree (0: it
// walks). Every invocation then tests the same instance at the same time,
// one shape's code at a time, where a walk's lanes reach different nodes
// and instances; on the CPU driver that cost more than the few extra
// tests up to about 8 instances (docs/performance.md).
override FLAT_TOP_LEVEL: u32 = 0u;

var<private> steps_left: u32;
// The traversal stack: one per invocation, which its queries use in turn
// (a mesh or CSG walk inside a top-level walk, above the top level's
// entries). A private array in each query would be zero-filled at each of
// its calls; this one is filled once per invocation, and only as long as
// the scene needs (docs/performance-history.md).
var<private> trace_stack: array<u32, TRACE_STACK>;
// The triangle (index into `triangles`) of the closest hit a trace last
// returned, when that hit is on a triangle mesh (texture coordinates).
var<private> hit_triangle: u32;
var<private> mesh_triangle: u32;
var<private> overflowed: bool;

// A world-space hit: unit outward normals (not yet flipped towards the ray).
struct TraceHit {
    t: f32,
    instance: u32,
    normal: vec3<f32>,
    geometric: vec3<f32>,
    // Material id: a CSG leaf's own material, else the instance's.
    material: u32,
}

fn take_step() -> bool {
    if steps_left == 0u {
        overflowed = true;
        return false;
    }
    steps_left -= 1u;
    return true;
}

// Entry and exit t of a node's box, clipped to (t_min, t_max); a miss has
// entry > exit. The exit is pushed out by BOX_EXIT_SLACK (relative), so that
// rounding never culls a box that a ray through a vertex or an edge on its
// face touches (BOX_EXIT_SLACK: lib/limits.wgsl, generated from
// src/accel/intersect.rs, which says how large).
fn node_span(node: BvhNode, o: vec3<f32>, inv_d: vec3<f32>, t_min: f32, t_max: f32) -> vec2<f32> {
    let t1 = (node.bounds_min - o) * inv_d;
    let t2 = (node.bounds_max - o) * inv_d;
    let lo = min(t1, t2);
    let hi = max(t1, t2);
    let near = max(max(max(lo.x, lo.y), lo.z), t_min);
    let exit = min(min(hi.x, hi.y), hi.z);
    let far = min(exit * select(1.0 + BOX_EXIT_SLACK, 1.0 - BOX_EXIT_SLACK, exit < 0.0), t_max);
    return vec2<f32>(near, far);
}

// The entry t of node i's box, or 3.0e38 on a miss; `top`: node i is the
// top-level tree's (lib/scene_bindings.wgsl, load_tree_node).
fn box_entry(i: u32, o: vec3<f32>, inv_d: vec3<f32>, t_min: f32, t_max: f32, top: bool) -> f32 {
    let s = node_span(load_tree_node(i, top), o, inv_d, t_min, t_max);
    return select(3.0e38, s.x, s.x <= s.y);
}

// One step of descent from inner node `node`: tests both children's boxes
// here (so a popped node needs no second test), continues into the nearer
// child that is hit and pushes the farther one. Returns the next node, or
// NO_HIT when neither child is hit (the caller pops). `top`: the walk is
// the top-level tree's.
fn descend(node: BvhNode, o: vec3<f32>, inv_d: vec3<f32>, t_min: f32, t_max: f32, sp: ptr<function, u32>, top: bool) -> u32 {
    let left = node.left_or_first;
    let t_left = box_entry(left, o, inv_d, t_min, t_max, top);
    let t_right = box_entry(left + 1u, o, inv_d, t_min, t_max, top);
    let hit_left = t_left < 3.0e38;
    let hit_right = t_right < 3.0e38;
    if hit_left && hit_right {
        if *sp >= TRACE_STACK {
            overflowed = true;
            return NO_HIT;
        }
        let near_left = t_left <= t_right;
        trace_stack[*sp] = select(left, left + 1u, near_left);
        *sp += 1u;
        return select(left + 1u, left, near_left);
    }
    if hit_left {
        return left;
    }
    if hit_right {
        return left + 1u;
    }
    return NO_HIT;
}

// The closest triangle of a mesh's bottom-level BVH, in object space. It
// uses `trace_stack` above `base`, where the caller's entries end.
fn intersect_mesh(root: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, base: u32) -> ObjectHit {
    let inv_d = 1.0 / d;
    let root_node = load_node(root);
    let ray = triangle_ray(o, d, root_node.bounds_min, root_node.bounds_max);
    var best = NO_HIT;
    var best_tuv = vec3<f32>(0.0);
    var t_best = t_max;
    var sp = base;
    let root_span = node_span(root_node, o, inv_d, t_min, t_max);
    var current = select(NO_HIT, root, root_span.x <= root_span.y);
    loop {
        if current == NO_HIT {
            if sp == base {
                break;
            }
            sp -= 1u;
            current = trace_stack[sp];
        }
        if !take_step() {
            break;
        }
        let node = load_node(current);
        if node.count == 0u {
            current = descend(node, o, inv_d, t_min, t_best, &sp, false);
            continue;
        }
        for (var k = node.left_or_first; k < node.left_or_first + node.count; k++) {
            let h = triangle_tuv(ray, k, t_min, t_best);
            if h.w != 0.0 {
                t_best = h.x;
                best = k;
                best_tuv = h.xyz;
            }
        }
        current = NO_HIT;
    }
    if best == NO_HIT {
        return no_hit();
    }
    mesh_triangle = best;
    return triangle_hit(best, best_tuv);
}

fn intersect_instance_shape(shape: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, base: u32) -> ObjectHit {
    let s = load_shape(shape);
    object_material = CSG_NO_MATERIAL;
    if CSG_ENABLED && s.kind == SHAPE_CSG {
        // Rays that miss the solid's bounding sphere skip the evaluation.
        if !csg_bound_may_hit(s.params, o, d, t_min, t_max) {
            return no_hit();
        }
        if CSG_FAST_LEAVES > 0u && s.csg_fast != 0u {
            return intersect_csg_fast(s.csg_fast, o, d, t_min, t_max);
        }
        if CSG_INTERPRETER {
            return intersect_csg(s.blas_root, o, d, t_min, t_max, base);
        }
        return no_hit();
    }
    if s.kind == SHAPE_MESH {
        if !MESHES_ENABLED {
            return no_hit();
        }
        return intersect_mesh(s.blas_root, o, d, t_min, t_max, base);
    }
    return intersect_analytic(s.kind, s.params, o, d, t_min, t_max);
}

// No hit within t_max.
fn trace_miss(t_max: f32) -> TraceHit {
    var h: TraceHit;
    h.t = t_max;
    h.instance = NO_HIT;
    return h;
}

// A top-level query's closest hit so far: `best`, with its normals still
// in the hit instance's object space until finish_hit.
struct TopHit {
    best: TraceHit,
    object_normal: vec3<f32>,
    object_geometric: vec3<f32>,
}

fn top_miss(t_max: f32) -> TopHit {
    var top: TopHit;
    top.best = trace_miss(t_max);
    return top;
}

// Tests GPU instance `inst` against the world ray (o, d) in (t_min,
// top.best.t), keeping its hit in `top` where there is one, which it
// returns. `base`: where a mesh or CSG walk's own stack entries start.
// With `skip_meshes`, triangle meshes are ignored (hybrid mode rasterizes
// them).
fn test_instance(inst: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, skip_meshes: bool, base: u32, top: ptr<function, TopHit>) -> bool {
    // One read of the instance (where tables are read by selection, one
    // tree of branches: lib/scene_bindings.wgsl).
    let instance = load_instance(inst);
    let shape = instance.shape;
    if skip_meshes && load_shape(shape).kind == SHAPE_MESH {
        return false;
    }
    let m = instance.object_from_world;
    let h = intersect_instance_shape(shape, (m * vec4<f32>(o, 1.0)).xyz, (m * vec4<f32>(d, 0.0)).xyz, t_min, (*top).best.t, base);
    if !h.hit {
        return false;
    }
    (*top).best.t = h.t;
    (*top).best.instance = inst;
    (*top).best.material = select(object_material, instance.material, object_material == CSG_NO_MATERIAL);
    (*top).object_normal = h.normal;
    (*top).object_geometric = h.geometric;
    hit_triangle = mesh_triangle;
    return true;
}

// `top`'s hit with its normals in world space.
fn finish_hit(top: TopHit) -> TraceHit {
    var best = top.best;
    if best.instance != NO_HIT {
        let to_world = load_instance(best.instance).normal_from_object;
        best.normal = normalize((to_world * vec4<f32>(top.object_normal, 0.0)).xyz);
        best.geometric = normalize((to_world * vec4<f32>(top.object_geometric, 0.0)).xyz);
    }
    return best;
}

// The closest hit of the world ray (o, d) in (t_min, t_max), each
// invocation walking on its own. With `any_hit`, returns the first hit found
// (shadow rays). With `skip_meshes`, triangle meshes are ignored (hybrid
// mode rasterizes them).
fn trace_each(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    var top = top_miss(t_max);
    if FLAT_TOP_LEVEL > 0u {
        // One step per instance tested, as the walk spends one per node.
        for (var k = 0u; k < FLAT_TOP_LEVEL; k++) {
            if !take_step() {
                break;
            }
            if test_instance(k, o, d, t_min, skip_meshes, 0u, &top) && any_hit {
                return top.best;
            }
        }
        return finish_hit(top);
    }
    let inv_d = 1.0 / d;
    var sp = 0u;
    var current = select(NO_HIT, 0u, box_entry(0u, o, inv_d, t_min, t_max, true) < 3.0e38);
    loop {
        if current == NO_HIT {
            if sp == 0u {
                break;
            }
            sp -= 1u;
            current = trace_stack[sp];
        }
        if !take_step() {
            break;
        }
        let node = load_tree_node(current, true);
        if node.count == 0u {
            current = descend(node, o, inv_d, t_min, top.best.t, &sp, true);
            continue;
        }
        for (var k = node.left_or_first; k < node.left_or_first + node.count; k++) {
            if test_instance(tlas_items[k], o, d, t_min, skip_meshes, sp, &top) && any_hit {
                return top.best;
            }
        }
        current = NO_HIT;
    }
    return finish_hit(top);
}

// The top-level trace the passes call (`trace_converged`, `trace_masked`,
// `any_lane`; closest or any hit of a world ray): `trace_each` above
// (lib/trace_bvh.wgsl); in the packet variant of a pass, the packet walk of
// lib/trace_packet.wgsl; in the driver variant, the wgpu ray query of
// lib/trace_rq.wgsl (src/gpu/shader.rs swaps the include).
#include "lib/trace_bvh.wgsl"
