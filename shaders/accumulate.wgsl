// Accumulate pass: this sample's G-buffer colour, with toon outlines drawn
// from depth, normal and id discontinuities, added to the float accumulator.
// accum[p].w counts the samples, so resolve divides by it.
//
// Two kernels, dispatched one after the other in one compute pass:
// `main`, which accumulates the pixels of the tiles
// shaders/outline_tiles.wgsl left unmarked (0: over their list where the
// trace pass accumulates, else over every tile) and leaves the others
// (OUTLINE_MARK_SEARCH: `outlined`'s; OUTLINE_MARK_TRACED: no outline
// reaches them, and the trace pass already added their colour,
// shaders/trace.wgsl); and `outlined`, dispatched indirectly over the marked tiles
// alone (the list outline_tiles.wgsl appends to), which loads the tile
// and searches for outlines (where an image has more tiles than one
// dispatch may count, over every tile instead, the unmarked ones stopping
// at once). On the CPU driver a kernel's code costs its 8-lane groups
// even where none runs it: in one kernel, the search's code cost the
// default scene's unmarked tiles about 2.5 ms of an 11 ms pass
// (docs/performance-history.md, seventeenth session).

#include "lib/types.wgsl"
#include "lib/scene_bindings.wgsl"

// Group 0: the scene (lib/scene_bindings.wgsl). Group 1: this pass's own.
@group(1) @binding(0) var<uniform> frame: FrameUniforms;
// Bindings 1-3 and 6-8: the G-buffer (lib/gbuffer.wgsl).
#include "lib/gbuffer.wgsl"
#include "lib/outline.wgsl"
@group(1) @binding(4) var<storage, read_write> accum: array<vec4<f32>>;
#include "lib/accum.wgsl"
// From shaders/outline_tiles.wgsl, run just before: OUTLINE_MARK_SEARCH
// where a pixel of the tile may take an outline (an outlined object in
// reach, and the tile not provably the smooth inside of one object), which
// `main` leaves to `outlined`; OUTLINE_MARK_TRACED where the trace pass
// accumulated the tile, which `main` leaves alone; else 0.
@group(1) @binding(5) var<storage, read> tile_marks: array<u32>;
// The marked tiles' indices (row by row numbering), in no particular
// order: `outlined`'s workgroup k takes tile_list[k]. Where the trace pass
// accumulates, the tiles left to `main` follow from the end: `main`'s
// workgroup k takes tile_list[tiles - 1 - k]. Written by
// outline_tiles.wgsl, which also counts them into the indirect dispatches.
@group(1) @binding(9) var<storage, read> tile_list: array<u32>;
// `outlined`'s indirect dispatch (x, y, z workgroups) and, in word 3, how
// it finds its tile: OUTLINE_TILES_LISTED, workgroup k takes tile_list[k];
// else the dispatch is every tile's workgroup, and the unmarked ones stop at
// once (images with more tiles than one dispatch's x may count: over
// about 4096 x 4096 pixels, since 8 px tiles are used only where they can
// be listed; or where tests turn the list off: src/render/accumulate.rs).
// From word MAIN_DISPATCH_WORD: `main`'s indirect dispatch over the tiles
// left to it, used where the trace pass accumulates and the list is read.
@group(1) @binding(10) var<storage, read> outline_dispatch: array<u32, OUTLINE_DISPATCH_WORDS>;
const OUTLINE_TILES_LISTED: u32 = 1u;

// The tile's edge in pixels, one invocation each: 8 or 16, set per
// pipeline (src/render/accumulate.rs, accumulate_tile_px).
override ACCUMULATE_TILE: u32 = MAX_ACCUMULATE_TILE;
// From the generated lib/limits.wgsl: MAX_ACCUMULATE_TILE, the larger edge;
// MAX_OUTLINE_RADIUS (outlines wider than this many pixels are drawn this
// wide); TILE_TEXELS, the workgroup tile with its halo,
// (MAX_ACCUMULATE_TILE + 2 * MAX_OUTLINE_RADIUS)^2 texels at most;
// TILE_ROW_TEXELS, its rows by the workgroup's columns.
// DEPTH_JUMP (lib/limits.wgsl): q is in front of p when its view depth is
// smaller by this fraction.
// Normals more than 60 degrees apart make a crease.
const CREASE_COS: f32 = 0.5;
// From this outline radius on, each pixel first proves, in O(r) steps,
// whether its search could find anything (pixel_needs_search), and only
// the pixels that could search: below it, the proof costs more than the
// (2r + 1)^2 search it saves.
const PIXEL_PROOF_MIN_RADIUS: i32 = 3;
// Per texel of the tile (pixel_needs_search): SOURCE_BIT where it draws
// outlines on other pixels (its material's outline is 1 px or wider);
// ROUGH_BIT where it is not provably the smooth inside of one object
// together with its right and lower neighbours; UNEVEN_BIT where an
// object's texel fails the test on its own (lib/outline.wgsl,
// smooth_texel), so that the search may find an edge between the pixel
// and itself.
const SOURCE_BIT: u32 = 1u;
const ROUGH_BIT: u32 = 2u;
const UNEVEN_BIT: u32 = 4u;

// The G-buffer around this workgroup's pixels, loaded once and shared, so
// the outline search reads workgroup memory rather than textures. Each
// texel's word in tile_id holds its id (0: background) in the low
// INSTANCE_ID_BITS bits (lib/limits.wgsl; SceneBuffers::upload refuses
// scenes whose ids need more) and its reach above them (texel_reach):
// the search's width test and its id comparisons read one word. On the
// CPU driver each word a pixel reads from workgroup memory is a gather of
// 8 loads; with the width in an array of its own, and the test a branch,
// the accumulate pass took 1.10x the time at 100,000 spheres
// (docs/performance-history.md). Equal words are equal ids (one
// instance, one material, one reach), and a zero word is the background.
var<workgroup> tile_id: array<u32, TILE_TEXELS>;
var<workgroup> tile_normal_depth: array<vec4<f32>, TILE_TEXELS>;
const REACH_SHIFT: u32 = INSTANCE_ID_BITS;
const ID_MASK: u32 = (1u << REACH_SHIFT) - 1u;

// A texel's reach: 0 on the background, else 1 + the floor of the square
// of its material's outline width (at most 255, beyond any square of an
// offset the search makes, 2 MAX_OUTLINE_RADIUS^2). The search takes a
// texel at integer offset (dx, dy) where dx^2 + dy^2 <= width^2, that is
// where dx^2 + dy^2 < reach.
fn texel_reach(width: f32) -> u32 {
    return 1u + u32(min(floor(width * width), 254.0));
}
// The bits per texel, then, per row of the tile and
// column of the workgroup, those bits ORed over the 2r + 1 texels
// centred on that column (pixel_needs_search). The lavapipe limit of
// 32 KiB of workgroup memory holds all of these at the widest radius.
var<workgroup> tile_bits: array<u32, TILE_TEXELS>;
var<workgroup> row_bits: array<u32, TILE_ROW_TEXELS>;
// The `outlined` kernel's workgroup is one row of ACCUMULATE_TILE
// invocations: invocation `first` of them loads (and, below, marks and
// ORs) every ACCUMULATE_TILE-th texel from its own.
fn load_tile(origin: vec2<i32>, span: i32, first: u32) {
    let size = vec2<i32>(frame.size_px);
    for (var k = i32(first); k < span * span; k += i32(ACCUMULATE_TILE)) {
        let q = origin + vec2<i32>(k % span, k / span);
        var word = 0u;
        var nd = vec4<f32>(0.0);
        if all(q >= vec2<i32>(0)) && all(q < size) {
            let id = gbuffer_id(q);
            if id != 0u {
                nd = gbuffer_normal_depth(q);
                let width = load_material(load_instance(id - 1u).material).outline_width_px;
                word = id | (texel_reach(width) << REACH_SHIFT);
            }
        }
        tile_id[k] = word;
        tile_normal_depth[k] = nd;
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
    var best_id = 0u;
    // No texel farther than the widest outline can reach p. Below the cap,
    // frame.max_outline_px is that width, so each row of the search spans
    // only the disk's chord (its half-width floored, with a margin over the
    // rounding: a texel it keeps but the disk does not is still refused by
    // the width test below). At the cap a wider material may reach the
    // square's corners, so the rows span the whole square. At r = 1 the
    // rows span the square too (the width test refuses what lies outside
    // the disk), so that a constant r = 1 unrolls.
    let reach2 = frame.max_outline_px * frame.max_outline_px;
    let capped = frame.max_outline_px >= f32(MAX_OUTLINE_RADIUS);
    for (var dy = -r; dy <= r; dy++) {
        let room = reach2 - f32(dy * dy);
        var rx = r;
        if !capped && r > 1 {
            rx = i32(floor(min(sqrt(max(room, 0.0)) + 1.0e-3, f32(r))));
        }
        for (var dx = -rx; dx <= rx; dx++) {
            let k = (c.y + dy) * span + c.x + dx;
            let id_q = tile_id[k];
            // The width test, as a mask rather than a branch: 8
            // neighbouring pixels rarely agree on it.
            let reaches = u32(dx * dx + dy * dy) < (id_q >> REACH_SHIFT);
            let nd_q = tile_normal_depth[k];
            var edge = id_p == 0u;
            if !edge {
                let in_front = nd_q.w < nd_p.w * (1.0 - DEPTH_JUMP);
                let other_object = id_q != id_p && nd_q.w < nd_p.w;
                let crease = dot(nd_q.xyz, nd_p.xyz) < CREASE_COS && nd_q.w <= nd_p.w;
                edge = in_front || other_object || crease;
            }
            if reaches && edge && nd_q.w < best_depth {
                best_depth = nd_q.w;
                best_id = id_q;
            }
        }
    }
    if best_id == 0u {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(load_material(load_instance((best_id & ID_MASK) - 1u).material).outline_color, 1.0);
}

// SOURCE_BIT, ROUGH_BIT and UNEVEN_BIT of every texel of the loaded tile
// (span x span).
// A pair with a neighbour outside the tile is in no searched pixel's
// square, so it is not checked.
fn mark_texels(span: i32, r: i32, first: u32) {
    let bounds = smooth_step_bounds(r);
    for (var k = i32(first); k < span * span; k += i32(ACCUMULATE_TILE)) {
        let id = tile_id[k];
        let nd = tile_normal_depth[k];
        let alone = smooth_texel(nd);
        var even = id != 0u && alone;
        if even && k % span + 1 < span {
            even = tile_id[k + 1] == id && smooth_pair(nd, tile_normal_depth[k + 1], bounds);
        }
        if even && k / span + 1 < span {
            even = tile_id[k + span] == id && smooth_pair(nd, tile_normal_depth[k + span], bounds);
        }
        tile_bits[k] = select(0u, SOURCE_BIT, (id >> REACH_SHIFT) >= 2u) | select(ROUGH_BIT, 0u, even)
            | select(0u, UNEVEN_BIT, id != 0u && !alone);
    }
}

// Per tile row and workgroup column x, the texel bits ORed over tile
// columns x .. x + 2r (the 2r + 1 texels centred on pixel column x).
fn or_rows(span: i32, r: i32, first: u32) {
    let w = i32(ACCUMULATE_TILE);
    for (var e = i32(first); e < span * w; e += w) {
        let row = (e / w) * span + e % w;
        var bits = 0u;
        for (var dx = 0; dx <= 2 * r; dx++) {
            bits |= tile_bits[row + dx];
        }
        row_bits[e] = bits;
    }
}

// Whether the pixel at workgroup position l could take an outline, from
// the bits of the (2r + 1)^2 square its search covers (or_rows, then the
// column here). The search takes only texels q within their own outline
// width of the pixel p: p itself, or a source (a texel 1 px away or more
// needs a width of 1 px or more). So without a source in the square,
// only p itself can make an edge with p: a background pixel never does,
// an object's pixel only where it fails smooth_texel on its own
// (UNEVEN_BIT). With a source in the square, a background pixel takes
// its outline; an object's pixel takes one only from a texel of another
// object or the background, or across a depth edge or a crease. Where
// every texel of the square is smooth with its right and lower
// neighbours (same object, lib/outline.wgsl's per-step bounds), any two
// texels the search compares are joined by a path of at most 2r such
// steps inside the square, so no pair makes an edge (outline_tiles.wgsl's
// argument, for one pixel's square rather than a tile's).
fn pixel_needs_search(l: vec2<i32>, span: i32, r: i32) -> bool {
    let w = i32(ACCUMULATE_TILE);
    var bits = 0u;
    for (var dy = 0; dy <= 2 * r; dy++) {
        bits |= row_bits[(l.y + dy) * w + l.x];
    }
    let centre = (l.y + r) * span + l.x + r;
    if (tile_bits[centre] & UNEVEN_BIT) != 0u {
        return true;
    }
    let background = tile_id[centre] == 0u;
    return (bits & SOURCE_BIT) != 0u && (background || (bits & ROUGH_BIT) != 0u);
}

// The outline radius the search uses: integer offsets within a disk of
// radius w have |dx|, |dy| <= floor(w).
fn outline_radius() -> i32 {
    return i32(floor(min(frame.max_outline_px, f32(MAX_OUTLINE_RADIUS))));
}

// The pixels of the unmarked tiles (all of them when the scene has no
// outline 1 px or wider: r = 0, and no marks were made; the renderer then
// runs this pass only where the trace pass did not already accumulate
// every pixel). Over the listed ones where the trace pass accumulates (and
// the list is read), else over every tile.
//
// One invocation per column of the tile, down its rows: on the CPU driver
// each group of 8 invocations a workgroup runs first works out their ids
// (a division each), so fewer invocations doing more pixels each cost
// less. A row of 8 (one SIMD program) down 8 rows: in the default raster
// frame this kernel took 0.78 of the time it took with one invocation a
// pixel (docs/performance-history.md, twenty-fifth session).
@compute @workgroup_size(ACCUMULATE_TILE, 1)
fn main(
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let tiles = (frame.size_px + vec2<u32>(ACCUMULATE_TILE - 1u)) / ACCUMULATE_TILE;
    let total = tiles.x * tiles.y;
    let outlines = outline_radius() > 0;
    let listed = outlines && frame.trace_accumulates != 0u && outline_dispatch[3] == OUTLINE_TILES_LISTED;
    let count = select(total, outline_dispatch[MAIN_DISPATCH_WORD], listed);
    // Workgroup w of n takes the w-th, (w + n)-th, ... of its tiles, as the
    // trace pass does: a GPU gets one workgroup per tile (a grid of every
    // tile, or the indirect dispatch's count of listed ones: one pass of
    // the loop), the CPU driver a few that loop (render::accumulate).
    for (var k = wg.y * groups.x + wg.x; k < count; k += groups.x * groups.y) {
        var tile = k;
        if listed {
            tile = tile_list[total - 1u - k];
        } else if outlines && tile_marks[tile] != 0u {
            // The whole workgroup agrees, so the CPU driver skips the rest at once.
            continue;
        }
        let column = vec2<u32>(tile % tiles.x, tile / tiles.x) * ACCUMULATE_TILE + vec2<u32>(lid.x, 0u);
        for (var row = 0u; row < ACCUMULATE_TILE; row++) {
            let gid = column + vec2<u32>(0u, row);
            if gid.x < frame.size_px.x && gid.y < frame.size_px.y {
                add_sample(gid, gbuffer_color(vec2<i32>(gid)));
            }
        }
    }
}

// The marked tiles, one workgroup each: the tile and its halo loaded into
// workgroup memory, then each pixel's outline search. One invocation per
// column of the tile, down its rows, as `main` (csg_grid's accumulate
// pass 0.77 of the time with one invocation a pixel, paired; the default
// hybrid frame's 0.87; docs/performance-history.md, twenty-fifth
// session).
@compute @workgroup_size(ACCUMULATE_TILE, 1)
fn outlined(
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let r = outline_radius();
    let span = i32(ACCUMULATE_TILE) + 2 * r;
    let tiles_x = (frame.size_px.x + ACCUMULATE_TILE - 1u) / ACCUMULATE_TILE;
    let listed = outline_dispatch[3] == OUTLINE_TILES_LISTED;
    let total = tiles_x * ((frame.size_px.y + ACCUMULATE_TILE - 1u) / ACCUMULATE_TILE);
    let count = select(total, outline_dispatch[0], listed);
    // Workgroup w of n takes the w-th, (w + n)-th, ... of its tiles, as in
    // `main` (where the driver keeps barriers in a loop right: lavapipe
    // before Mesa 25 gets one workgroup per tile, gpu::Gpu::barriers_loop).
    for (var k = wg.y * groups.x + wg.x; k < count; k += groups.x * groups.y) {
        var tile = k;
        if listed {
            tile = tile_list[k];
        } else if tile_marks[tile] != OUTLINE_MARK_SEARCH {
            continue;
        }
        let origin = vec2<u32>(tile % tiles_x, tile / tiles_x) * ACCUMULATE_TILE;
        load_tile(vec2<i32>(origin) - vec2<i32>(r), span, lid.x);
        workgroupBarrier();
        if r >= PIXEL_PROOF_MIN_RADIUS {
            mark_texels(span, r, lid.x);
            workgroupBarrier();
            or_rows(span, r, lid.x);
            workgroupBarrier();
        }
        // Each invocation down its column of the tile, as in `main`.
        for (var row = 0u; row < ACCUMULATE_TILE; row++) {
            let l = vec2<u32>(lid.x, row);
            let gid = origin + l;
            // Wide outlines: only the pixels whose search could find
            // something search (the CPU driver skips it for 8 neighbours that
            // all agree).
            var search = true;
            if r >= PIXEL_PROOF_MIN_RADIUS {
                search = pixel_needs_search(vec2<i32>(l), span, r);
            }
            if gid.x < frame.size_px.x && gid.y < frame.size_px.y {
                var c = gbuffer_color(vec2<i32>(gid));
                if search {
                    // The usual outlines (1.5 px) search at r = 1: a call with
                    // the constant lets the driver unroll the 3 x 3 search
                    // (accumulate pass 0.92-0.94 of the time;
                    // docs/performance-history.md, twenty-first session).
                    var o: vec4<f32>;
                    if r == 1 {
                        o = outline_at(vec2<i32>(l) + vec2<i32>(1), span, 1);
                    } else {
                        o = outline_at(vec2<i32>(l) + vec2<i32>(r), span, r);
                    }
                    c = mix(c, o.rgb, o.a);
                }
                add_sample(gid, c);
            }
        }
        // The next tile's load overwrites what this one's search reads.
        workgroupBarrier();
    }
}
