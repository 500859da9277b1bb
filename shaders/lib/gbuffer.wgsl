// The G-buffer the accumulate pass and the outline marks read, at pixel q
// (inside the image): in raster mode the raster pass's textures; in hybrid
// and raytrace mode the storage buffers the trace pass wrote
// (src/render/targets.rs, TracedOutput: rows every TRACED_ROW_ALIGN_PX
// pixels, each texel in its texture's format, the colour as four halves),
// read where they are rather than first copied into textures. Which one is
// fixed per pipeline, so a kernel holds only its own reads.
//
// Includes: after `frame` (group 1, binding 0). Group 1 bindings 1-3 and
// 6-8 are these; a kernel binds those it reads.

#include "lib/color.wgsl"

override TRACED_GBUFFER: bool = false;
// In raster mode, whether the ids are the colour texture's alpha (the raster
// pass then has no id target: src/render/raster.rs, ids_in_color).
override IDS_IN_COLOR: bool = false;

@group(1) @binding(1) var color_tex: texture_2d<f32>;
@group(1) @binding(2) var normal_depth_tex: texture_2d<f32>;
@group(1) @binding(3) var id_tex: texture_2d<u32>;
@group(1) @binding(6) var<storage, read> traced_color: array<vec2<u32>>;
@group(1) @binding(7) var<storage, read> traced_normal_depth: array<vec4<f32>>;
@group(1) @binding(8) var<storage, read> traced_id: array<u32>;

fn traced_at(q: vec2<i32>) -> u32 {
    return traced_index(vec2<u32>(q), frame.size_px.x);
}

// Linear colour (a half-float texel: its halves widen exactly either way).
fn gbuffer_color(q: vec2<i32>) -> vec3<f32> {
    if TRACED_GBUFFER {
        return unpack_color_halves(traced_color[traced_at(q)]);
    }
    return textureLoad(color_tex, q, 0).rgb;
}

// World normal (xyz) and view depth (w).
fn gbuffer_normal_depth(q: vec2<i32>) -> vec4<f32> {
    if TRACED_GBUFFER {
        return traced_normal_depth[traced_at(q)];
    }
    return textureLoad(normal_depth_tex, q, 0);
}

// 0 for the background, else the GPU instance + 1.
fn gbuffer_id(q: vec2<i32>) -> u32 {
    if TRACED_GBUFFER {
        return traced_id[traced_at(q)];
    }
    if IDS_IN_COLOR {
        return u32(textureLoad(color_tex, q, 0).a);
    }
    return textureLoad(id_tex, q, 0).x;
}
