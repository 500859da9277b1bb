// Outline tiles: before the accumulate pass, one invocation per accumulate
// workgroup tile decides whether any pixel of the tile can take an outline,
// and writes OUTLINE_MARK_SEARCH (search) or 0 (skip; OUTLINE_MARK_TRACED
// where way 1 below holds and the trace pass accumulated the tile
// already, frame.trace_accumulates); each marked tile's index is also
// appended to `tile_list`, counted in the x workgroup count of
// `outline_dispatch` (zeroed before this pass), so the accumulate pass's
// `outlined` kernel runs one workgroup per marked tile and its `main`
// kernel skips them. Where the trace pass accumulates, the tiles left to
// `main` (marked 0) are listed too, from the list's end, and counted in
// `main`'s own indirect dispatch (from word MAIN_DISPATCH_WORD): `main` then runs over those
// alone. One invocation walks a whole tile, so this kernel
// needs no workgroup memory and no barrier (on the CPU driver a barrier
// costs about as much as the loads it orders).
//
// A tile is skipped when it is provably outline-free under the accumulate
// pass's rule (shaders/accumulate.wgsl, outline_at), in one of two ways:
// 1. Nothing within reach draws outlines: no texel of the tile or its halo
//    (the outline radius r) is a *source*, an object whose material's
//    outline is at least 1 px wide (a narrower one reaches no other pixel:
//    the nearest is 1 px away). The floor and the sky are most of many
//    scenes.
// 2. The tile is the smooth inside of one object: every texel of the tile
//    and its halo is that object (so no pixel has another object or the
//    background near it), and no two texels the search compares can make
//    a depth edge or a crease. The search compares pixels at most r apart
//    in x and in y, so a path of at most L = 2r steps between neighbouring
//    texels joins them, inside the tile and halo. Bounds on every
//    neighbouring pair then bound every compared pair along such a path:
//    view depths within a factor s = 0.96^(1/L) of each other make any two
//    within 0.96 (an edge needs 0.95), and normals at most 54 degrees / L
//    apart make any two at most 54 degrees apart (a crease needs 60; the
//    angle between directions obeys the triangle inequality), with every
//    normal at least 0.949 long, so their dot product is at least
//    0.9 * cos(54) = 0.53 against the crease's 0.5. The margins are far
//    wider than the rounding of these tests, so a skipped tile's search
//    would have found nothing, and the image does not change.

#include "lib/types.wgsl"
#include "lib/scene_bindings.wgsl"

// Group 0: the scene (lib/scene_bindings.wgsl). Group 1: this pass's own.
@group(1) @binding(0) var<uniform> frame: FrameUniforms;
// Bindings 2, 3, 7 and 8: the G-buffer's normal + depth and ids
// (lib/gbuffer.wgsl).
#include "lib/gbuffer.wgsl"
#include "lib/outline.wgsl"
// One word per accumulate workgroup, row by row: OUTLINE_MARK_SEARCH
// where the tile may take an outline, OUTLINE_MARK_TRACED where the trace
// pass accumulated it (source_tiles 0, with frame.trace_accumulates), else 0.
@group(1) @binding(4) var<storage, read_write> tile_marks: array<u32>;
// The accumulate pass's indirect dispatch of `outlined`: workgroup counts
// x, y, z (y and z stay 1); x counts the marked tiles. (Word 3 is the
// accumulate pass's: whether it reads the list.) From MAIN_DISPATCH_WORD:
// `main`'s, x counting the tiles left to it where the trace pass
// accumulates.
@group(1) @binding(5) var<storage, read_write> outline_dispatch: array<atomic<u32>, OUTLINE_DISPATCH_WORDS>;
// The marked tiles' indices, the first x of them written, in no order;
// where the trace pass accumulates, the tiles left to `main` from the end
// (the last word first).
@group(1) @binding(9) var<storage, read_write> tile_list: array<u32>;
// One word per tile, made on the CPU for each sample
// (accel::screen_tiles::reached_tiles): 0 where no texel of the tile or
// its halo can be a source, from the projected boxes of the instances
// whose outline reaches other pixels (1 everywhere where it is not made:
// scenes of many instances); also 0 where the CPU proves the tile and its
// halo the smooth inside of one sphere, with half of way 2's per-step
// bounds to spare (accel::screen_tiles::smooth_sphere_tiles; traced
// primary hits only). Such a tile is skipped without reading the
// G-buffer: way 1 or way 2 below, proven before the texels are read. Where the
// trace pass accumulates (frame.trace_accumulates), it has already added
// the colour of exactly these tiles' pixels (the CPU gives it the same
// flags: Renderer::tiles_seen_by).
@group(1) @binding(10) var<storage, read> source_tiles: array<u32>;

// The accumulate tile's edge in pixels, as the accumulate pipelines have
// it (src/render/accumulate.rs, accumulate_tile_px).
override ACCUMULATE_TILE: u32 = MAX_ACCUMULATE_TILE;
// From the generated lib/limits.wgsl: MAX_ACCUMULATE_TILE,
// MAX_OUTLINE_RADIUS, OUTLINE_TILES_WORKGROUP and DEPTH_JUMP.


fn outline_width(id: u32) -> f32 {
    return load_material(load_instance(id - 1u).material).outline_width_px;
}

@compute @workgroup_size(OUTLINE_TILES_WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let tiles = (frame.size_px + vec2<u32>(ACCUMULATE_TILE - 1u)) / ACCUMULATE_TILE;
    if gid.x >= tiles.x * tiles.y {
        return;
    }
    if source_tiles[gid.x] == 0u {
        if frame.trace_accumulates != 0u {
            tile_marks[gid.x] = OUTLINE_MARK_TRACED;
        } else {
            tile_marks[gid.x] = 0u;
        }
        return;
    }
    // The same radius and halo as the accumulate pass's.
    let r = i32(floor(min(frame.max_outline_px, f32(MAX_OUTLINE_RADIUS))));
    let tile = vec2<i32>(vec2<u32>(gid.x % tiles.x, gid.x / tiles.x) * ACCUMULATE_TILE);
    let size = vec2<i32>(frame.size_px);
    let core_hi = min(tile + vec2<i32>(i32(ACCUMULATE_TILE)), size);
    let lo = max(tile - vec2<i32>(r), vec2<i32>(0));
    let hi = min(core_hi + vec2<i32>(r), size);

    // Way 2's per-step bounds for paths of L = 2r steps (lib/outline.wgsl).
    let bounds = smooth_step_bounds(r);

    var any_source = false;
    // Still possibly the smooth inside of one object (way 2). Only worth
    // proving for an outlined object: a tile that is all one object
    // without an outline holds no source, and way 1 skips it (reading ids
    // only).
    let object = gbuffer_id(lo);
    var last_id = object;
    var last_width = 0.0;
    if object != 0u {
        last_width = outline_width(object);
    }
    var quiet = last_width >= 1.0;
    var left = vec4<f32>(0.0);
    for (var y = lo.y; y < hi.y; y++) {
        for (var x = lo.x; x < hi.x; x++) {
            let q = vec2<i32>(x, y);
            let id = gbuffer_id(q);
            quiet = quiet && id == object;
            if id != 0u && !any_source {
                if id != last_id {
                    last_id = id;
                    last_width = outline_width(id);
                }
                any_source = last_width >= 1.0;
            }
            if quiet {
                let nd = gbuffer_normal_depth(q);
                // Each texel on its own; the left and upper neighbours
                // passed this when they were read.
                quiet = smooth_texel(nd);
                if x > lo.x {
                    quiet = quiet && smooth_pair(nd, left, bounds);
                }
                if y > lo.y {
                    let up = gbuffer_normal_depth(q - vec2<i32>(0, 1));
                    quiet = quiet && smooth_pair(nd, up, bounds);
                }
                left = nd;
            }
            if any_source && !quiet {
                break;
            }
        }
        if any_source && !quiet {
            break;
        }
    }
    let marked = any_source && !quiet;
    tile_marks[gid.x] = select(0u, OUTLINE_MARK_SEARCH, marked);
    if marked {
        tile_list[atomicAdd(&outline_dispatch[0], 1u)] = gid.x;
    } else if frame.trace_accumulates != 0u {
        tile_list[tiles.x * tiles.y - 1u - atomicAdd(&outline_dispatch[MAIN_DISPATCH_WORD], 1u)] = gid.x;
    }
}
