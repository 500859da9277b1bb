// Ray-batch kernel: the closest hit (or, built with ANY_HIT, any hit: the
// shadow-ray query) of each ray in a buffer, by the same traversal the
// trace pass runs. Used by tests (GPU against the CPU reference) and
// benchmarks; each ray gets the per-query step budget the CPU reference
// uses.

#include "lib/types.wgsl"
#include "lib/scene_bindings.wgsl"
#include "lib/intersect.wgsl"
#include "lib/traverse.wgsl"
#include "lib/csg.wgsl"

// Group 0: the scene (lib/scene_bindings.wgsl). Group 1: this pass's own.
@group(1) @binding(0) var<storage, read> rays: array<GpuRay>;
@group(1) @binding(1) var<storage, read_write> hits: array<GpuHit>;

// RAY_BATCH_WORKGROUP: lib/limits.wgsl (generated).

// True: each ray stops at the first hit it finds (what a shadow ray asks).
override ANY_HIT: bool = false;

@compute @workgroup_size(RAY_BATCH_WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    // Invocations past the end trace the last ray again and write nothing:
    // the packet walk (lib/trace_packet.wgsl) needs every lane of a subgroup.
    let n = arrayLength(&rays);
    let i = min(gid.x, n - 1u);
    steps_left = MAX_TRAVERSAL_STEPS;
    overflowed = false;
    let ray = rays[i];
    let h = trace_converged(ray.origin.xyz, ray.dir.xyz, ray.origin.w, ray.dir.w, false, ANY_HIT);
    var out: GpuHit;
    out.t = h.t;
    out.instance = h.instance;
    out.normal = h.normal;
    out.steps = MAX_TRAVERSAL_STEPS - steps_left;
    out.overflow = u32(overflowed);
    if gid.x < n {
        hits[i] = out;
    }
}
