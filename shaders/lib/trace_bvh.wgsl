// The top-level trace through celray's own two-level BVH, each invocation
// walking on its own (`trace_each`, lib/traverse.wgsl, which includes this).
// The passes call the three functions below, which every traversal include
// defines (lib/trace_packet.wgsl, lib/trace_rq.wgsl), always with every
// invocation of the subgroup making the call together (none has returned
// or branched away), as the packet walk needs.

// The closest or any hit of the world ray (o, d) in (t_min, t_max).
fn trace_converged(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    return trace_each(o, d, t_min, t_max, skip_meshes, any_hit);
}

// trace_converged for the invocations where `wants` holds, the others
// getting a miss (no walk at all here).
fn trace_masked(wants: bool, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    if !wants {
        return trace_miss(t_max);
    }
    return trace_each(o, d, t_min, t_max, skip_meshes, any_hit);
}

// Whether `b` holds for any invocation of the subgroup making this call
// together. Each invocation here walks alone: its own `b`.
fn any_lane(b: bool) -> bool {
    return b;
}
