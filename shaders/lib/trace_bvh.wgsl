// The top-level trace through celray's own two-level BVH, each invocation
// walking on its own (`trace_each`, lib/traverse.wgsl, which includes this).

fn trace(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    return trace_each(o, d, t_min, t_max, skip_meshes, any_hit);
}

// `trace` where every invocation of the subgroup makes the call together
// (none has returned or branched away): the packet variant
// (lib/trace_packet.wgsl) walks those calls as packets.
fn trace_converged(o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32, skip_meshes: bool, any_hit: bool) -> TraceHit {
    return trace_each(o, d, t_min, t_max, skip_meshes, any_hit);
}
