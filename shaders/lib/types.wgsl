// Layout twins of the Rust structs in src/gpu/twins.rs (same names, same
// fields; a test parses this file with naga and compares offsets). The
// limits shared with Rust come from lib/limits.wgsl, which the composer
// generates from the Rust constants (src/gpu/shader.rs, limits_header).

#include "lib/limits.wgsl"

// Per-sample camera and frame data.
struct FrameUniforms {
    // Projection * view, with this sample's sub-pixel jitter folded in.
    clip_from_world: mat4x4<f32>,
    eye_in_world: vec4<f32>,
    // Unit camera forward; view depth of p is dot(p - eye, view_forward).
    view_forward: vec4<f32>,
    ambient: vec4<f32>,
    background: vec4<f32>,
    size_px: vec2<u32>,
    light_count: u32,
    // 0 for the first sample after a reset: accumulation overwrites.
    sample_index: u32,
    jitter_px: vec2<f32>,
    // Widest outline of any material, in pixels: the outline search radius.
    max_outline_px: f32,
    seed: u32,
    // Inverse of clip_from_world: unprojects pixel centres into the same
    // primary rays the rasterizer samples.
    world_from_clip: mat4x4<f32>,
    // RENDER_MODE_*: which passes find primary visibility.
    mode: u32,
    // Mirror bounces after the primary hit.
    max_bounces: u32,
    // Offset of secondary ray origins along the normal (scene-scaled).
    ray_epsilon: f32,
    // 1 where the trace pass adds the colour of the tiles its tile words
    // flag (TILE_TRACE_ACCUMULATES: no outline reaches them) to the
    // accumulator itself, so the outline marks flag them
    // OUTLINE_MARK_TRACED and the accumulate pass leaves them alone.
    trace_accumulates: u32,
    // 1 for a dispatch that only completes the last sample's G-buffer
    // (src/render/mod.rs, Renderer::complete_gbuffer): the tiles that
    // sample left unstored (TILE_GBUFFER_SKIPS) store their normal, depth
    // and id, the others return at once, and nothing is shaded or
    // accumulated.
    gbuffer_only: u32,
    _pad1: u32,
    _pad2: u32,
    _pad3: u32,
}

const RENDER_MODE_RASTER: u32 = 0u;
const RENDER_MODE_HYBRID: u32 = 1u;
const RENDER_MODE_RAYTRACE: u32 = 2u;

// A light: w of position_or_direction is 0 for a directional light (xyz is
// the unit direction the light travels, normalized on the CPU) and 1 for a
// point light (xyz = position).
struct GpuLight {
    position_or_direction: vec4<f32>,
    // colour * intensity; w = 1 when the light casts shadows.
    radiance: vec4<f32>,
}

const SHADING_BLINN_PHONG: u32 = 0u;
const SHADING_TOON: u32 = 1u;

struct GpuMaterial {
    base_color: vec3<f32>,
    shininess: f32,
    specular_color: vec3<f32>,
    // Toon: the hard highlight where N.H exceeds this (and N.L > 0): the
    // material's specular_threshold^(1 / shininess), rounded down to an
    // f32, so that the test (N.H)^shininess > specular_threshold needs no
    // pow per pixel (src/render/scene_buffers.rs, highlight_cos).
    highlight_cos: f32,
    outline_color: vec3<f32>,
    outline_width_px: f32,
    rim_color: vec3<f32>,
    // Toon: rim where 1 - N.V exceeds this; above 1 means no rim.
    rim_threshold: f32,
    model: u32,
    band_count: u32,
    reflectivity: f32,
    roughness: f32,
    // band_count - 1 increasing N.L thresholds, packed four to a vec4;
    // unused slots hold 2.0 (above any N.L).
    thresholds: array<vec4<f32>, 4>,
    // Procedural checker (shaders/lib/texture.wgsl); size 0: none.
    checker_a: vec3<f32>,
    checker_size: f32,
    checker_b: vec3<f32>,
    // Layer of the base-colour texture array, or NO_TEXTURE.
    texture_layer: u32,
    uv_scale: vec2<f32>,
    // 1: nearest-texel sampling.
    texture_nearest: u32,
    _pad: u32,
}

const NO_TEXTURE: u32 = 0xffffffffu;

// A mesh map word: the array layer in the low bits, the glTF sampler's
// settings above (all zero: repeat, linear, trilinear); see
// shaders/lib/texture.wgsl's sample_map.
const MAP_LAYER_MASK: u32 = 0xffu;
const MAP_WRAP_S_SHIFT: u32 = 8u;
const MAP_WRAP_T_SHIFT: u32 = 10u;
const MAP_WRAP_REPEAT: u32 = 0u;
const MAP_WRAP_CLAMP: u32 = 1u;
const MAP_WRAP_MIRROR: u32 = 2u;
const MAP_MAG_NEAREST: u32 = 4096u;
const MAP_MIN_NEAREST: u32 = 8192u;
const MAP_MIP_NEAREST: u32 = 16384u;
const MAP_NO_MIPS: u32 = 32768u;

struct GpuInstance {
    world_from_object: mat4x4<f32>,
    // Inverse of world_from_object: takes rays into object space.
    object_from_world: mat4x4<f32>,
    // Inverse transpose of world_from_object: takes normals to world space.
    normal_from_object: mat4x4<f32>,
    material: u32,
    shape: u32,
    // 1 when world_from_object has a negative determinant (flips winding).
    mirrored: u32,
    _pad: u32,
}

const TONE_MAP_CLAMP: u32 = 0u;
const TONE_MAP_REINHARD: u32 = 1u;

struct ResolveUniforms {
    width: u32,
    exposure: f32,
    _pad: vec2<u32>,
}

// Which shadow rays of one light can meet something at all (twin of
// GpuShadowCull, src/accel/layout.rs; built by src/accel/shadow_cull.rs):
// the axes (u, v) across a directional light with the grid's lower corner
// in w, static planes tested exactly (row y of their object_from_world),
// and a grid of dims cells in shadow_cells from first_cell: 0 where no
// occluder lands, k + 1 where only instance k (a sphere or a box) does,
// CULL_CELL_MANY otherwise.
const CULL_CELL_MANY: u32 = 0xffffffffu;

struct GpuShadowCull {
    u: vec4<f32>,
    v: vec4<f32>,
    planes: array<vec4<f32>, MAX_CULL_PLANES>,
    cells_per_unit: vec2<f32>,
    dims: vec2<u32>,
    first_cell: u32,
    plane_count: u32,
    // 0: every shadow ray of this light is cast.
    enabled: u32,
    // Instance k's occluder list: the record of SHADOW_LIST_WORDS words at
    // shadow_cells[first_list + k * SHADOW_LIST_WORDS] (a header: the count
    // and SHADOW_LIST_CONVEX, or SHADOW_LIST_WALK; then the instances).
    // 0: no lists.
    first_list: u32,
    // Instance k's world bounding sphere (centre, radius) as the f32 bits
    // of shadow_cells[first_sphere + 4 k ..]; 0: none (with the lists).
    first_sphere: u32,
    _pad: array<u32, 3>,
}

// A node of a bounding volume hierarchy: a leaf (count > 0) holds items
// left_or_first .. left_or_first + count; an inner node's children are
// nodes left_or_first and left_or_first + 1.
struct BvhNode {
    bounds_min: vec3<f32>,
    left_or_first: u32,
    bounds_max: vec3<f32>,
    count: u32,
}

// A mesh triangle in object space with its vertex normals; (p_k.w, n_k.w)
// are corner k's texture coordinates.
struct GpuTriangle {
    p0: vec4<f32>,
    p1: vec4<f32>,
    p2: vec4<f32>,
    n0: vec4<f32>,
    n1: vec4<f32>,
    n2: vec4<f32>,
}

// A base shape: SHAPE_* kind, parameters (radius, half extents, height),
// and for meshes the root node of its bottom-level BVH.
struct GpuShape {
    params: vec4<f32>,
    kind: u32,
    blas_root: u32,
    csg_fast: u32,
    _pad1: u32,
}

struct GpuRay {
    origin: vec4<f32>,
    dir: vec4<f32>,
}

struct GpuHit {
    normal: vec3<f32>,
    t: f32,
    instance: u32,
    steps: u32,
    overflow: u32,
    _pad: u32,
}

// One instruction of a CSG postfix program (lib/csg.wgsl).
struct GpuCsgOp {
    op: u32,
    arg: u32,
}

struct GpuCsgLeaf {
    leaf_from_csg: mat4x4<f32>,
    csg_normal_from_leaf: mat4x4<f32>,
    params: vec4<f32>,
    kind: u32,
    blas_root: u32,
    material: u32,
    table: u32,
}

// Index of pixel p in the trace pass's output buffers (src/render/targets.rs,
// TracedOutput) for an image `width` pixels wide: rows start every
// TRACED_ROW_ALIGN_PX pixels. The trace pass writes them, lib/gbuffer.wgsl
// reads them.
fn traced_index(p: vec2<u32>, width: u32) -> u32 {
    let row_px = (width + TRACED_ROW_ALIGN_PX - 1u) & ~(TRACED_ROW_ALIGN_PX - 1u);
    return p.y * row_px + p.x;
}
