// Ray-batch kernel: the closest hit of each ray in a buffer, by the same
// traversal the trace pass runs. Used by tests (GPU against the CPU
// reference) and benchmarks; each ray gets the per-query step budget the
// CPU reference uses.

#include "lib/types.wgsl"
#include "lib/intersect.wgsl"
#include "lib/traverse.wgsl"
#include "lib/csg.wgsl"

@group(0) @binding(0) var<storage, read> instances: array<GpuInstance>;
@group(0) @binding(1) var<storage, read> shapes: array<GpuShape>;
@group(0) @binding(2) var<storage, read> nodes: array<BvhNode>;
@group(0) @binding(3) var<storage, read> triangles: array<GpuTriangle>;
@group(0) @binding(4) var<storage, read> tlas_items: array<u32>;
@group(0) @binding(5) var<storage, read> rays: array<GpuRay>;
@group(0) @binding(6) var<storage, read_write> hits: array<GpuHit>;
@group(0) @binding(7) var<storage, read> csg_ops: array<GpuCsgOp>;
@group(0) @binding(8) var<storage, read> csg_leaves: array<GpuCsgLeaf>;

const RAY_BATCH_WORKGROUP: u32 = 64u;

@compute @workgroup_size(RAY_BATCH_WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&rays) {
        return;
    }
    steps_left = MAX_TRAVERSAL_STEPS;
    overflowed = false;
    let ray = rays[i];
    let h = trace(ray.origin.xyz, ray.dir.xyz, ray.origin.w, ray.dir.w, false, false);
    var out: GpuHit;
    out.t = h.t;
    out.instance = h.instance;
    out.normal = h.normal;
    out.steps = MAX_TRAVERSAL_STEPS - steps_left;
    out.overflow = u32(overflowed);
    hits[i] = out;
}
