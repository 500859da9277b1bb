// Outline tiles: before the accumulate pass, one invocation per accumulate
// workgroup tile marks whether the tile, with its halo of the outline
// radius, holds a texel that could draw an outline on another pixel: an
// object whose material's outline is at least 1 px wide (a narrower one
// reaches no other pixel). The accumulate pass reads the mark once per
// workgroup and skips loading the tile, its barrier and the search where
// it is clear: the floor and the sky, outlined by nothing, are most of
// many scenes. One invocation walks a whole tile, so this kernel needs no
// workgroup memory and no barrier (on the CPU driver a barrier costs
// about as much as the loads it orders).

#include "lib/types.wgsl"
#include "lib/scene_bindings.wgsl"

// Group 0: the scene (lib/scene_bindings.wgsl). Group 1: this pass's own.
@group(1) @binding(0) var<uniform> frame: FrameUniforms;
@group(1) @binding(1) var id_tex: texture_2d<u32>;
// One word per accumulate workgroup, row by row: 1 where the tile may
// take an outline.
@group(1) @binding(2) var<storage, read_write> tile_marks: array<u32>;

// From the generated lib/limits.wgsl: ACCUMULATE_WORKGROUP (the tile's
// side), MAX_OUTLINE_RADIUS and OUTLINE_TILES_WORKGROUP.

@compute @workgroup_size(OUTLINE_TILES_WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tiles = (frame.size_px + vec2<u32>(ACCUMULATE_WORKGROUP - 1u)) / ACCUMULATE_WORKGROUP;
    if gid.x >= tiles.x * tiles.y {
        return;
    }
    // The same radius and halo as the accumulate pass's.
    let r = i32(floor(min(frame.max_outline_px, f32(MAX_OUTLINE_RADIUS))));
    let tile = vec2<i32>(vec2<u32>(gid.x % tiles.x, gid.x / tiles.x) * ACCUMULATE_WORKGROUP);
    let size = vec2<i32>(frame.size_px);
    let lo = max(tile - vec2<i32>(r), vec2<i32>(0));
    let hi = min(tile + vec2<i32>(i32(ACCUMULATE_WORKGROUP) + r), size);
    var mark = 0u;
    for (var y = lo.y; y < hi.y && mark == 0u; y++) {
        for (var x = lo.x; x < hi.x; x++) {
            let id = textureLoad(id_tex, vec2<i32>(x, y), 0).x;
            if id != 0u && materials[instances[id - 1u].material].outline_width_px >= 1.0 {
                mark = 1u;
                break;
            }
        }
    }
    tile_marks[gid.x] = mark;
}
