// The scene's bind group (group 0), declared once for every pass that reads
// the scene (raster, trace, ray_batch, accumulate): what SceneBuffers uploads.
// Its Rust twin is SCENE_LAYOUT in src/render/scene_buffers.rs, bound once
// per scene (SceneBuffers::bind_group) and shared by the passes;
// tests/shaders.rs checks every binding's number and type against it. A
// pass's own resources are in group 1 (PASS_GROUP), the driver's
// acceleration structures in group 2 (lib/trace_rq.wgsl).

#include "lib/types.wgsl"

@group(0) @binding(0) var<storage, read> instances: array<GpuInstance>;
@group(0) @binding(1) var<storage, read> materials: array<GpuMaterial>;
@group(0) @binding(2) var<storage, read> lights: array<GpuLight>;
@group(0) @binding(3) var<storage, read> shapes: array<GpuShape>;
@group(0) @binding(4) var<storage, read> nodes: array<BvhNode>;
@group(0) @binding(5) var<storage, read> triangles: array<GpuTriangle>;
@group(0) @binding(6) var<storage, read> tlas_items: array<u32>;
@group(0) @binding(7) var<storage, read> csg_ops: array<GpuCsgOp>;
@group(0) @binding(8) var<storage, read> csg_leaves: array<GpuCsgLeaf>;
// Per mesh triangle: its mesh's own base-colour map word (layer and glTF
// sampler bits, see lib/types.wgsl), or NO_TEXTURE.
@group(0) @binding(9) var<storage, read> triangle_maps: array<u32>;
// Base-colour maps (lib/texture.wgsl): one layer per image, a 1x1 white
// layer when the scene has none.
@group(0) @binding(10) var base_color_maps: texture_2d_array<f32>;
@group(0) @binding(11) var map_linear: sampler;
@group(0) @binding(12) var map_nearest: sampler;
