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

// The small tables again, as uniform buffers (src/gpu/uniform_tables.rs):
// on the CPU driver a uniform read at a per-invocation index is one
// branchless gather, a storage read a loop over the 8 lanes with two
// branches a word. Bit TABLE_* of UNIFORM_TABLES (set per pipeline, from
// which tables of the scene fit) says which copy the accessors below read;
// the other one's code is not in the pipeline. The CSG instructions are
// packed two to a vec4 (a uniform array's stride is a multiple of 16
// bytes): the storage layout. Six copies at most: Mesa 22.3's lavapipe
// corrupts its heap with 8 uniform buffers in one stage (it reports 15),
// and a pass adds its own (frame uniforms). The top-level items have none:
// unpacking a word from a vec4 cost more than the copy saved (0.97x).
override UNIFORM_TABLES: u32 = 0u;
@group(0) @binding(13) var<uniform> nodes_u: array<BvhNode, UNIFORM_NODES>;
@group(0) @binding(14) var<uniform> instances_u: array<GpuInstance, UNIFORM_INSTANCES>;
@group(0) @binding(15) var<uniform> shapes_u: array<GpuShape, UNIFORM_SHAPES>;
@group(0) @binding(16) var<uniform> materials_u: array<GpuMaterial, UNIFORM_MATERIALS>;
@group(0) @binding(17) var<uniform> csg_ops_u: array<vec4<u32>, UNIFORM_CSG_OP_VECS>;
@group(0) @binding(18) var<uniform> csg_leaves_u: array<GpuCsgLeaf, UNIFORM_CSG_LEAVES>;
// The node and triangle tables again as plain words (the same buffers as
// `nodes` and `triangles`; compute passes only), for the packet walk's loads
// of one word a lane (lib/trace_packet.wgsl).
@group(0) @binding(19) var<storage, read> node_words: array<u32>;
@group(0) @binding(20) var<storage, read> triangle_words: array<u32>;

// Tables read by selection (src/gpu/uniform_tables.rs, SelectedTables): on
// the CPU driver a table read at a per-invocation index is a gather even
// where the 8 lanes of its SIMD program want the same element, while a
// read at a constant index is one load for all 8. Where not 0, the
// material (instance) table's element count, at most MAX_SELECTED: then
// load_material (load_instance) takes element i from a tree of branches
// over the constant indices (select_material and select_instance, in the
// generated lib/select_tables.wgsl).
override SELECT_MATERIALS: u32 = 0u;
override SELECT_INSTANCES: u32 = 0u;
#include "lib/select_tables.wgsl"

fn uniform_table(table: u32) -> bool {
    return (UNIFORM_TABLES & table) != 0u;
}

// Node i of the top-level tree (`top`) or of a mesh's (a literal at every
// call, so only one branch stays in the pipeline). The top-level tree's
// nodes come first, so its copy may hold them where the whole table does
// not fit (TABLE_TOP_NODES).
fn load_tree_node(i: u32, top: bool) -> BvhNode {
    if uniform_table(TABLE_NODES) || (top && uniform_table(TABLE_TOP_NODES)) {
        return nodes_u[i];
    }
    return nodes[i];
}

// Node i of a mesh's tree.
fn load_node(i: u32) -> BvhNode {
    return load_tree_node(i, false);
}

fn load_instance(i: u32) -> GpuInstance {
    if SELECT_INSTANCES != 0u {
        return select_instance(i);
    }
    return load_instance_at(i);
}

fn load_instance_at(i: u32) -> GpuInstance {
    if uniform_table(TABLE_INSTANCES) {
        return instances_u[i];
    }
    return instances[i];
}

fn load_shape(i: u32) -> GpuShape {
    if uniform_table(TABLE_SHAPES) {
        return shapes_u[i];
    }
    return shapes[i];
}

fn load_material(i: u32) -> GpuMaterial {
    if SELECT_MATERIALS != 0u {
        return select_material(i);
    }
    return load_material_at(i);
}

fn load_material_at(i: u32) -> GpuMaterial {
    if uniform_table(TABLE_MATERIALS) {
        return materials_u[i];
    }
    return materials[i];
}

fn load_csg_op(i: u32) -> GpuCsgOp {
    if uniform_table(TABLE_CSG_OPS) {
        let pair = csg_ops_u[i / 2u];
        let op = select(pair.xy, pair.zw, (i & 1u) == 1u);
        return GpuCsgOp(op.x, op.y);
    }
    return csg_ops[i];
}

fn load_csg_leaf(i: u32) -> GpuCsgLeaf {
    if uniform_table(TABLE_CSG_LEAVES) {
        return csg_leaves_u[i];
    }
    return csg_leaves[i];
}
