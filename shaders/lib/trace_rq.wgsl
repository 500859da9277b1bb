// The top-level trace through the driver's acceleration structures (wgpu
// ray queries): the driver variant of lib/trace_bvh.wgsl, same signature and
// result. Built by src/render/driver_accel.rs: one bottom level per base
// shape (a mesh's triangles, or one AABB for an analytic or CSG shape), one
// top-level instance per GPU instance with world_from_object as its
// transform and the GPU instance index as its custom index.
//
// Triangles are opaque: the driver commits the closest one itself. An AABB
// candidate runs the exact intersection of lib/intersect.wgsl (or the CSG
// interval program, whose closed-mesh leaves walk celray's own BVH of that
// leaf) on the object-space ray, the same numbers the software path uses,
// and reports its t. Rays are not renormalized, so t is the world t.

@group(2) @binding(0) var scene_tlas: acceleration_structure;
// Per base shape: the index in `triangles` of a mesh's first triangle (the
// bottom level's primitive i is triangles[base + i]); unused for others.
@group(2) @binding(1) var<storage, read> rq_mesh_base: array<u32>;

// Top-level instance masks: hybrid primary rays skip meshes.
const RQ_MASK_MESH: u32 = 1u;
const RQ_MASK_OTHER: u32 = 2u;

fn trace(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    var best: TraceHit;
    best.t = t_max;
    best.instance = NO_HIT;
    let flags = RAY_FLAG_NONE;
    let mask = select(0xffu, RQ_MASK_OTHER, skip_meshes);
    var rq: ray_query;
    rayQueryInitialize(&rq, scene_tlas, RayDesc(flags, mask, t_min, t_max, o, d));
    // The nearest generated (AABB) hit so far, tracked here rather than read
    // back from the query: lavapipe (Mesa 25.0.7) does not lower the
    // committed distance after rayQueryGenerateIntersection, so a later,
    // farther AABB could replace a nearer one. Triangles (opaque) are
    // committed by the driver, whose committed triangle t is reliable.
    var gen_normal = vec3<f32>(0.0);
    var gen_geometric = vec3<f32>(0.0);
    var gen_material = 0u;
    var gen_instance = NO_HIT;
    var gen_t = t_max;
    // The triangle (index in `triangles`) of a generated hit on a CSG mesh
    // leaf, for its texture coordinates (hit_triangle, lib/traverse.wgsl).
    var gen_triangle = 0u;
    loop {
        if !rayQueryProceed(&rq) {
            break;
        }
        if !take_step() {
            rayQueryTerminate(&rq);
            break;
        }
        let cand = rayQueryGetCandidateIntersection(&rq);
        if cand.kind != RAY_QUERY_INTERSECTION_AABB {
            continue;
        }
        let committed = rayQueryGetCommittedIntersection(&rq);
        var t_hi = gen_t;
        if committed.kind == RAY_QUERY_INTERSECTION_TRIANGLE {
            t_hi = min(t_hi, committed.t);
        }
        let inst = cand.instance_custom_data;
        let m = load_instance(inst).object_from_world;
        let h = intersect_instance_shape(load_instance(inst).shape, (m * vec4<f32>(o, 1.0)).xyz, (m * vec4<f32>(d, 0.0)).xyz, t_min, t_hi, 0u);
        if h.hit {
            gen_normal = h.normal;
            gen_geometric = h.geometric;
            gen_material = select(object_material, load_instance(inst).material, object_material == CSG_NO_MATERIAL);
            gen_instance = inst;
            gen_triangle = mesh_triangle;
            // A named value: naga 30 does not emit an expression written
            // inside this call's arguments before the call.
            let t_hit = h.t;
            gen_t = t_hit;
            rayQueryGenerateIntersection(&rq, t_hit);
            if any_hit {
                break;
            }
        }
    }
    let c = rayQueryGetCommittedIntersection(&rq);
    let triangle = c.kind == RAY_QUERY_INTERSECTION_TRIANGLE && c.t < gen_t;
    if !triangle && gen_instance == NO_HIT {
        return best;
    }
    var inst = gen_instance;
    best.t = gen_t;
    var object_normal = gen_normal;
    var object_geometric = gen_geometric;
    best.material = gen_material;
    hit_triangle = gen_triangle;
    if triangle {
        inst = c.instance_custom_data;
        best.t = c.t;
        hit_triangle = rq_mesh_base[load_instance(inst).shape] + c.primitive_index;
        let tri = triangles[hit_triangle];
        let u = c.barycentrics.x;
        let v = c.barycentrics.y;
        object_normal = tri.n0.xyz * (1.0 - u - v) + tri.n1.xyz * u + tri.n2.xyz * v;
        object_geometric = cross(tri.p1.xyz - tri.p0.xyz, tri.p2.xyz - tri.p0.xyz);
        best.material = load_instance(inst).material;
    }
    best.instance = inst;
    let to_world = load_instance(inst).normal_from_object;
    best.normal = normalize((to_world * vec4<f32>(object_normal, 0.0)).xyz);
    best.geometric = normalize((to_world * vec4<f32>(object_geometric, 0.0)).xyz);
    return best;
}

// `trace` as the passes call it (lib/trace_bvh.wgsl): the same query.
fn trace_converged(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    return trace(o, d, t_min, t_max, skip_meshes, any_hit);
}

// `trace` for the invocations where `wants` holds, the others getting a
// miss (lib/trace_bvh.wgsl).
fn trace_masked(wants: bool, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    if !wants {
        return trace_miss(t_max);
    }
    return trace(o, d, t_min, t_max, skip_meshes, any_hit);
}

// Whether `b` holds for any invocation making this call together: its own
// (lib/trace_bvh.wgsl).
fn any_lane(b: bool) -> bool {
    return b;
}
