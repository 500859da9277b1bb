// Accumulate pass: this sample's G-buffer colour, with toon outlines drawn
// from depth, normal and id discontinuities, added to the float accumulator.
// accum[p].w counts the samples, so resolve divides by it.

#include "lib/types.wgsl"
#include "lib/scene_bindings.wgsl"

// Group 0: the scene (lib/scene_bindings.wgsl). Group 1: this pass's own.
@group(1) @binding(0) var<uniform> frame: FrameUniforms;
// Bindings 1-3 and 6-8: the G-buffer (lib/gbuffer.wgsl).
#include "lib/gbuffer.wgsl"
@group(1) @binding(4) var<storage, read_write> accum: array<vec4<f32>>;
// From shaders/outline_tiles.wgsl, run just before: 1 where a pixel of
// this workgroup's tile may take an outline (an outlined object in reach,
// and the tile not provably the smooth inside of one object). Read-only
// storage read at the workgroup's own index is uniform, so the tile load
// and its barrier can sit under it.
@group(1) @binding(5) var<storage, read> tile_marks: array<u32>;

// From the generated lib/limits.wgsl: ACCUMULATE_WORKGROUP;
// MAX_OUTLINE_RADIUS (outlines wider than this many pixels are drawn this
// wide); TILE_TEXELS, the workgroup tile with its halo,
// (ACCUMULATE_WORKGROUP + 2 * MAX_OUTLINE_RADIUS)^2 texels at most.
// DEPTH_JUMP (lib/limits.wgsl): q is in front of p when its view depth is
// smaller by this fraction.
// Normals more than 60 degrees apart make a crease.
const CREASE_COS: f32 = 0.5;

// The G-buffer around this workgroup's pixels, loaded once and shared, so
// the outline search reads workgroup memory rather than textures.
var<workgroup> tile_id: array<u32, TILE_TEXELS>;
var<workgroup> tile_normal_depth: array<vec4<f32>, TILE_TEXELS>;
var<workgroup> tile_material: array<u32, TILE_TEXELS>;
// The square of the texel's outline width, or -1 on the background: the
// search's first test reads this one array.
var<workgroup> tile_width2: array<f32, TILE_TEXELS>;
fn load_tile(origin: vec2<i32>, span: i32, first: u32) {
    let size = vec2<i32>(frame.size_px);
    for (var k = i32(first); k < span * span; k += i32(ACCUMULATE_WORKGROUP * ACCUMULATE_WORKGROUP)) {
        let q = origin + vec2<i32>(k % span, k / span);
        var id = 0u;
        var nd = vec4<f32>(0.0);
        var material = 0u;
        var width2 = -1.0;
        if all(q >= vec2<i32>(0)) && all(q < size) {
            id = gbuffer_id(q);
            if id != 0u {
                nd = gbuffer_normal_depth(q);
                material = instances[id - 1u].material;
                let width = materials[material].outline_width_px;
                width2 = width * width;
            }
        }
        tile_id[k] = id;
        tile_normal_depth[k] = nd;
        tile_material[k] = material;
        tile_width2[k] = width2;
    }
}

// The outline colour covering the pixel at tile position c, if any (a = 1).
// An outline is drawn on the far side of a discontinuity: the pixel takes
// the outline of the nearest pixel q within q's material's width (in pixels:
// the width does not change with resolution) that is in front of it, or on
// its background.
fn outline_at(c: vec2<i32>, span: i32, r: i32) -> vec4<f32> {
    let k_p = c.y * span + c.x;
    let id_p = tile_id[k_p];
    let nd_p = tile_normal_depth[k_p];
    var best_depth = 3.0e38;
    var best_material = 0xffffffffu;
    // No texel farther than the widest outline can reach p. Below the cap,
    // frame.max_outline_px is that width, so each row of the search spans
    // only the disk's chord (its half-width floored, with a margin over the
    // rounding: a texel it keeps but the disk does not is still refused by
    // the width test below). At the cap a wider material may reach the
    // square's corners, so the rows span the whole square.
    let reach2 = frame.max_outline_px * frame.max_outline_px;
    let capped = frame.max_outline_px >= f32(MAX_OUTLINE_RADIUS);
    for (var dy = -r; dy <= r; dy++) {
        let room = reach2 - f32(dy * dy);
        var rx = r;
        if !capped {
            rx = i32(floor(min(sqrt(max(room, 0.0)) + 1.0e-3, f32(r))));
        }
        for (var dx = -rx; dx <= rx; dx++) {
            let k = (c.y + dy) * span + c.x + dx;
            if f32(dx * dx + dy * dy) > tile_width2[k] {
                continue;
            }
            let id_q = tile_id[k];
            let nd_q = tile_normal_depth[k];
            var edge = id_p == 0u;
            if !edge {
                let in_front = nd_q.w < nd_p.w * (1.0 - DEPTH_JUMP);
                let other_object = id_q != id_p && nd_q.w < nd_p.w;
                let crease = dot(nd_q.xyz, nd_p.xyz) < CREASE_COS && nd_q.w <= nd_p.w;
                edge = in_front || other_object || crease;
            }
            if edge && nd_q.w < best_depth {
                best_depth = nd_q.w;
                best_material = tile_material[k];
            }
        }
    }
    if best_material == 0xffffffffu {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(materials[best_material].outline_color, 1.0);
}

@compute @workgroup_size(ACCUMULATE_WORKGROUP, ACCUMULATE_WORKGROUP)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
) {
    // Integer offsets within a disk of radius w have |dx|, |dy| <= floor(w).
    let r = i32(floor(min(frame.max_outline_px, f32(MAX_OUTLINE_RADIUS))));
    let span = i32(ACCUMULATE_WORKGROUP) + 2 * r;
    let tiles_x = (frame.size_px.x + ACCUMULATE_WORKGROUP - 1u) / ACCUMULATE_WORKGROUP;
    // Tiles that nothing can outline skip the tile, its barrier and the
    // search (the whole workgroup agrees, so the CPU driver skips the code).
    let outlined = r > 0 && tile_marks[wg.y * tiles_x + wg.x] != 0u;
    if outlined {
        load_tile(vec2<i32>(wg.xy * ACCUMULATE_WORKGROUP) - vec2<i32>(r), span, li);
        workgroupBarrier();
    }
    if gid.x >= frame.size_px.x || gid.y >= frame.size_px.y {
        return;
    }
    var c = gbuffer_color(vec2<i32>(gid.xy));
    if outlined {
        let o = outline_at(vec2<i32>(lid.xy) + vec2<i32>(r), span, r);
        c = mix(c, o.rgb, o.a);
    }
    let i = gid.y * frame.size_px.x + gid.x;
    if frame.sample_index == 0u {
        accum[i] = vec4<f32>(c, 1.0);
    } else {
        accum[i] += vec4<f32>(c, 1.0);
    }
}
