// Trace pass: per pixel, the same primary ray the raster pass samples;
// analytic shapes (hybrid) or everything (raytrace) are traced through the
// two-level BVH (or, in the driver variant, the driver's acceleration
// structures) and composited against the raster depth; then shadow rays
// and mirror or glossy reflections against the whole scene, shaded by the same
// functions as the raster pass. Writes the G-buffer the accumulate pass reads.

#include "lib/types.wgsl"
#include "lib/scene_bindings.wgsl"
#include "lib/shading.wgsl"
#include "lib/intersect.wgsl"
#include "lib/traverse.wgsl"
#include "lib/csg.wgsl"
#include "lib/random.wgsl"
#include "lib/texture.wgsl"
#include "lib/color.wgsl"

// Group 0: the scene (lib/scene_bindings.wgsl). Group 1: this pass's own.
@group(1) @binding(0) var<uniform> frame: FrameUniforms;
// [0]: pixels whose traversal ran out of its step budget.
@group(1) @binding(1) var<storage, read_write> stats: array<atomic<u32>>;
@group(1) @binding(2) var raster_normal_depth: texture_2d<f32>;
@group(1) @binding(3) var raster_id: texture_2d<u32>;
// The G-buffer this pass writes, as buffers that are then copied into the
// traced textures (src/render/targets.rs, TracedOutput): on the CPU driver
// a storage-texture store costs several times a buffer store. Rows start
// every TRACED_ROW_ALIGN_PX pixels; each texel is in its texture's format
// (the colour as four halves).
@group(1) @binding(4) var<storage, read_write> out_color: array<vec2<u32>>;
@group(1) @binding(5) var<storage, read_write> out_normal_depth: array<vec4<f32>>;
@group(1) @binding(6) var<storage, read_write> out_id: array<u32>;
// The raster pass's base colour (hybrid: rasterized hits).
@group(1) @binding(7) var raster_albedo: texture_2d<f32>;
// Per light, which shadow rays can meet anything (src/accel/shadow_cull.rs).
@group(1) @binding(8) var<storage, read> shadow_cull: array<GpuShadowCull>;
@group(1) @binding(9) var<storage, read> shadow_cells: array<u32>;
// Per 8 x 8 tile of pixels (one workgroup), the instances its primary rays
// can meet, or PRIMARY_TILE_WALK (src/accel/screen_tiles.rs): made on the
// CPU for each sample's camera. After the records, one word per tile:
// TILE_MESH_MAY_SHOW in hybrid mode where a rasterized mesh may show (its
// raster G-buffer is the background elsewhere, unread), and
// TILE_TRACE_ACCUMULATES where no outline can reach the tile.
@group(1) @binding(10) var<storage, read> primary_tiles: array<u32>;
// shadow_cells again, as vec4s: the instances' bounding spheres
// (may_meet_sphere), each loaded at once rather than word by word.
@group(1) @binding(11) var<storage, read> shadow_spheres: array<vec4<f32>>;
// The float accumulator (shaders/accumulate.wgsl's): in the tiles no
// outline can reach, this pass adds each pixel's colour itself, as the
// accumulate pass would (lib/accum.wgsl), instead of storing it in
// out_color for that pass to copy there. The outline marks flag those
// tiles OUTLINE_MARK_TRACED (frame.trace_accumulates), and the accumulate
// pass leaves them alone.
@group(1) @binding(12) var<storage, read_write> accum: array<vec4<f32>>;
#include "lib/accum.wgsl"

// TRACE_WORKGROUP, MAX_INVOCATION_STEPS (loop iterations one pixel may
// spend on traversal, all rays together: well under lavapipe's silent cut
// at ~65,535) and FAR_DEPTH (the view depth written where no surface is
// hit) come from the generated lib/limits.wgsl.

// What the scene and settings can reach, fixed per pipeline so that code no
// pixel can need is not in the kernel at all (the CPU driver pays for code
// that 8 neighbouring invocations might need, and Mesa 22.3 for all of it).
// False only when it changes nothing: no light casts shadows; no material
// reflects (or max_bounces is 0); no reflective material is rough.
override SHADOWS_ENABLED: bool = true;
override REFLECTIONS_ENABLED: bool = true;
override GLOSSY_ENABLED: bool = true;
// The lights that cast shadows, one bit per light index (lights 0 to 31),
// and whether any light from index 32 on does. Shadow rays are cast in a
// loop over just these lights, so a light that casts none runs no
// traversal code for it (Mesa 22.3 runs both sides of every branch, so a
// shadow test under a run-time condition cost its code for every light).
override SHADOW_LIGHTS: u32 = 0xffffffffu;
override SHADOW_LIGHTS_FROM_32: bool = true;
// Whether a shadow ray may be answered by its receiver's occluder list
// (shadow_query): only where exactly one light casts shadows, a
// directional one (src/render/trace.rs, Variant::shadow_lists). With
// more, shade_hit casts the shadow rays in a loop, and there the list
// code alone slowed the default scene's trace pass by a third on
// lavapipe.
override SHADOW_LISTS: bool = true;
// Whether primary rays test their tile's instances (primary_tiles) instead
// of walking the BVH where the tile has a list (src/render/trace.rs,
// Variant::primary_tiles: scenes of up to MAX_TILED_INSTANCES instances).
override PRIMARY_TILES: bool = false;

// The closest hit of the primary ray (o, d) among the instances of the
// tile record at primary_tiles[r], tested as the BVH walk tests them; each
// test spends a step of the budget.
fn trace_listed(r: u32, o: vec3<f32>, d: vec3<f32>, skip_meshes: bool) -> TraceHit {
    var top = top_miss(3.0e38);
    for (var k = 0u; k < primary_tiles[r]; k++) {
        if !take_step() {
            break;
        }
        _ = test_instance(primary_tiles[r + 1u + k], o, d, 0.0, skip_meshes, 0u, &top);
    }
    return finish_hit(top);
}

// trace_listed for a tile whose record lists at most one instance, from
// the record's summary in the tile's flag word (TILE_RECORD_SHIFT): 0 for
// none, k + 1 for instance k. The same tests and steps, without reading
// the record.
fn trace_summary(summary: u32, o: vec3<f32>, d: vec3<f32>, skip_meshes: bool) -> TraceHit {
    var top = top_miss(3.0e38);
    if summary != 0u && take_step() {
        _ = test_instance(summary - 1u, o, d, 0.0, skip_meshes, 0u, &top);
    }
    return finish_hit(top);
}

// The normal facing the ray: two-sided surfaces are shaded on both sides.
fn facing_normal(h: TraceHit, d: vec3<f32>) -> vec3<f32> {
    return select(h.normal, -h.normal, dot(h.geometric, d) > 0.0);
}

// How the shadow ray from o along l (towards light i) is answered
// (src/accel/shadow_cull.rs, whose may_be_blocked and occluder_list are
// the CPU twins):
// - SHADOW_SKIP where it provably meets nothing, so a ray skipped for it
//   would have found no hit. A static plane is behind the ray where the
//   ray's object-space start height and direction, as the intersection
//   test computes them, have the same sign (beyond rounding). Every other
//   occluder's box lands on grid cells across the light: a ray meets none
//   where its cell is empty, or holds only the sphere or box whose lit
//   outside it leaves (`leaving`, else NO_HIT).
// - the index in shadow_cells of the occluder list of `receiver` (the
//   instance whose surface o is on), where it has one: the only instances
//   the ray can meet (list_blocks tests them);
// - else SHADOW_WALK: the ray walks the BVH.
const SHADOW_SKIP: u32 = 0u;
const SHADOW_WALK: u32 = 1u;

// The light's record is read field by field where used: loaded whole
// (`let c = shadow_cull[i]`), its planes, indexed in the loop, went
// through a private copy on the CPU driver (trace pass 0.954 of the time
// on csg_textbook, 0.967 on the default scene's hybrid frame, paired).
fn shadow_query(i: u32, o: vec3<f32>, l: vec3<f32>, receiver: u32, leaving: u32) -> u32 {
    if shadow_cull[i].enabled == 0u {
        return SHADOW_WALK;
    }
    for (var k = 0u; k < shadow_cull[i].plane_count; k++) {
        let r = shadow_cull[i].planes[k];
        let side = dot(r.xyz, o) + r.w;
        let along = dot(r.xyz, l);
        let side_err = PLANE_MARGIN * (dot(abs(r.xyz), abs(o)) + abs(r.w));
        let along_err = PLANE_MARGIN * dot(abs(r.xyz), abs(l));
        let behind = (side > side_err && along > along_err) || (side < -side_err && along < -along_err);
        if !behind {
            return SHADOW_WALK;
        }
    }
    let cu = shadow_cull[i].u;
    let cv = shadow_cull[i].v;
    let dims = shadow_cull[i].dims;
    let g = vec2<f32>(dot(cu.xyz, o) - cu.w, dot(cv.xyz, o) - cv.w) * shadow_cull[i].cells_per_unit;
    if any(g < vec2<f32>(0.0)) || any(g >= vec2<f32>(dims)) {
        return SHADOW_SKIP;
    }
    // A NaN origin fails both tests above: cast its ray.
    if any(g != g) {
        return SHADOW_WALK;
    }
    let cell = shadow_cells[shadow_cull[i].first_cell + u32(g.y) * dims.x + u32(g.x)];
    if cell == 0u || cell == leaving + 1u {
        return SHADOW_SKIP;
    }
    // The cell's own list of its occluders, where it has one.
    if SHADOW_LISTS && cell != CULL_CELL_MANY && (cell & CULL_CELL_LIST) != 0u {
        return cell & ~CULL_CELL_LIST;
    }
    let first_list = shadow_cull[i].first_list;
    if SHADOW_LISTS && first_list != 0u && receiver != NO_HIT {
        let r = first_list + receiver * SHADOW_LIST_WORDS;
        if shadow_cells[r] != SHADOW_LIST_WALK {
            return r;
        }
    }
    return SHADOW_WALK;
}

// Whether the ray from o along unit l may meet the world bounding sphere
// at shadow_cells[s] (centre, radius: shadow_cull.rs, bounding_sphere;
// a negative radius: no check, true): false only where the sphere lies
// wholly behind o or off the ray's line by more than its radius. The
// radius is grown by 1e-5 of the sizes involved, for the rounding of
// these sums and of a box's slab test, and by 6.4e-5 D^2 / R (D the
// centre's distance from o): a sphere's test, b^2 - ac near a tangent,
// may report a hit up to about 2e-7 D^2 / R beyond it, 16 times that
// where it is stretched 4x (the most a sphere with a check may be), and
// the margin is 20 times more. So a ray this refuses is one that the
// intersection test misses.
fn may_meet_sphere(s: u32, o: vec3<f32>, l: vec3<f32>) -> bool {
    let sphere = shadow_spheres[s / 4u];
    if sphere.w < 0.0 {
        return true;
    }
    let c = sphere.xyz - o;
    let along = dot(c, l);
    let off = c - l * along;
    let slack = 1.0e-5 * (sphere.w + dot(abs(sphere.xyz), vec3<f32>(1.0)) + dot(abs(o), vec3<f32>(1.0)))
        + 6.4e-5 * dot(c, c) / sphere.w;
    let radius = sphere.w + slack;
    return dot(off, off) <= radius * radius && along >= -radius;
}

// Whether an instance of the occluder list at shadow_cells[r] meets the
// ray (o, l) in (0, t_max), tested as the BVH walk tests it; the receiver
// is skipped where the list marks it a convex solid and the ray leaves its
// lit outside (`leaving`). Each instance costs a step of the budget.
// Where the instances are not in their uniform copy, one whose bounding
// sphere (from shadow_cells[spheres]) the ray misses is not tested
// further: on the CPU driver that skips the per-lane storage loads of its
// matrix (trace pass 0.92 of the time at 100,000 spheres; with the copy
// the check cost more than it saved, docs/performance-history.md).
fn list_blocks(r: u32, o: vec3<f32>, l: vec3<f32>, t_max: f32, leaving: u32, spheres: u32) -> bool {
    let header = shadow_cells[r];
    let skip = select(NO_HIT, leaving, (header & SHADOW_LIST_CONVEX) != 0u);
    for (var k = 0u; k < (header & (SHADOW_LIST_CONVEX - 1u)); k++) {
        let j = shadow_cells[r + 1u + k];
        if j == skip {
            continue;
        }
        if !take_step() {
            return false;
        }
        if !uniform_table(TABLE_INSTANCES) && !may_meet_sphere(spheres + 4u * j, o, l) {
            continue;
        }
        let inst = load_instance(j);
        let s = load_shape(inst.shape);
        let m = inst.object_from_world;
        let lo = (m * vec4<f32>(o, 1.0)).xyz;
        let ld = (m * vec4<f32>(l, 0.0)).xyz;
        // A cell's list may hold CSG solids evaluated by their truth table.
        if CSG_FAST_LEAVES > 0u && s.kind == SHAPE_CSG {
            if csg_bound_may_hit(s.params, lo, ld, 0.0, t_max) && intersect_csg_fast(s.csg_fast, lo, ld, 0.0, t_max).hit {
                return true;
            }
        } else if intersect_analytic(s.kind, s.params, lo, ld, 0.0, t_max).hit {
            return true;
        }
    }
    // A cell's list may go on with triangles of one static mesh: its
    // instance, then their indices, each tested as the mesh walk tests it
    // (the mesh's object space, the shear of its root's bounds).
    let triangles = header >> CELL_LIST_TRIANGLE_SHIFT;
    if MESHES_ENABLED && triangles != 0u {
        let at = r + 1u + (header & (SHADOW_LIST_CONVEX - 1u));
        let inst = load_instance(shadow_cells[at]);
        let m = inst.object_from_world;
        let root = load_node(load_shape(inst.shape).blas_root);
        let ray = triangle_ray((m * vec4<f32>(o, 1.0)).xyz, (m * vec4<f32>(l, 0.0)).xyz, root.bounds_min, root.bounds_max);
        for (var k = 0u; k < triangles; k++) {
            if !take_step() {
                return false;
            }
            if triangle_tuv(ray, shadow_cells[at + 1u + k], 0.0, t_max).w != 0.0 {
                return true;
            }
        }
    }
    return false;
}

// Whether the shadow ray from p (unit normal n) towards light i finds
// something in the way; a surface facing away from a light casts no ray
// (it is unlit by it anyway), nor does one that nothing can block, nor an
// invocation whose ray has ended (`going` false). `receiver`: the instance
// p is on; `leaving`: the same where it was hit from outside, else NO_HIT.
// Every invocation calls this together (trace_masked).
fn shadowed(i: u32, light: GpuLight, p: vec3<f32>, n: vec3<f32>, receiver: u32, leaving: u32, going: bool) -> bool {
    let ls = sample_light(i, light, p);
    let origin = p + n * frame.ray_epsilon;
    var how = SHADOW_SKIP;
    if going && light.radiance.w > 0.0 && dot(n, ls.to_light) > 0.0 {
        how = shadow_query(i, origin, ls.to_light, receiver, leaving);
    }
    var blocked = false;
    if SHADOW_LISTS && how > SHADOW_WALK {
        blocked = list_blocks(how, origin, ls.to_light, ls.distance, leaving, shadow_cull[i].first_sphere);
    }
    let walked = trace_masked(how == SHADOW_WALK, origin, ls.to_light, 0.0, ls.distance, false, true);
    return blocked || walked.instance != NO_HIT;
}

// Ambient, rim and every light, with a shadow ray per shadow-casting light
// the surface faces. The shadow rays go first (bit i of `blocked`: light i
// is blocked), then the lights are summed in their order.
fn shade_hit(p: vec3<f32>, n: vec3<f32>, v: vec3<f32>, m: GpuMaterial, receiver: u32, leaving: u32, going: bool) -> vec3<f32> {
    var c = shade_ambient(m, n, v, frame.ambient.rgb);
    var blocked = 0u;
    if SHADOWS_ENABLED {
        // One shadow-casting light (the usual sun): its call alone, not in
        // a loop of one, which the CPU driver may not unroll around a walk
        // (with the occluder-list code, the loop made the pass 1.26x slower).
        if countOneBits(SHADOW_LIGHTS) == 1u {
            // (& 31: without shadow lights this dead branch's shift must
            // still be a valid constant.)
            let i = firstTrailingBit(SHADOW_LIGHTS) & 31u;
            if i < frame.light_count && shadowed(i, lights[i], p, n, receiver, leaving, going) {
                blocked = 1u << i;
            }
        } else {
            var rest = SHADOW_LIGHTS;
            for (var k = 0u; k < countOneBits(SHADOW_LIGHTS); k++) {
                let i = firstTrailingBit(rest);
                rest &= rest - 1u;
                if i < frame.light_count && shadowed(i, lights[i], p, n, receiver, leaving, going) {
                    blocked |= 1u << i;
                }
            }
        }
    }
    // A fixed count (lib/shading.wgsl, light_loop_count) unrolls the loop.
    for (var i = 0u; i < light_loop_count(frame.light_count); i++) {
        let light = lights[i];
        let ls = sample_light(i, light, p);
        var visible = i >= 32u || (blocked & (1u << i)) == 0u;
        if SHADOWS_ENABLED && SHADOW_LIGHTS_FROM_32 && i >= 32u {
            visible = !shadowed(i, light, p, n, receiver, leaving, going);
        }
        if visible {
            c += shade_light(m, n, v, ls.to_light, ls.radiance);
        } else {
            c += shade_light_blocked(m, ls.radiance);
        }
    }
    return c;
}

// A glossy reflection direction: drawn from the Phong lobe around the mirror
// direction w, p(dir) proportional to cos^e(angle to w), with exponent
// e = 2 / roughness^2 - 2 (the usual roughness-to-Phong mapping), built in
// the orthonormal frame (u, v, w). Roughness 0 is the mirror itself.
// Directions below the surface are drawn again (up to 8 tries, then the
// mirror direction): rejection keeps the lobe's shape without darkening.
fn glossy_direction(w: vec3<f32>, n: vec3<f32>, roughness: f32, pixel_key: u32, bounce: u32) -> vec3<f32> {
    if !GLOSSY_ENABLED || roughness <= 0.0 {
        return w;
    }
    let a = max(roughness, 1e-3);
    let e = 2.0 / (a * a) - 2.0;
    let helper = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), abs(w.x) > 0.9);
    let u = normalize(cross(helper, w));
    let v = cross(w, u);
    let stream = hash_u32(frame.sample_index ^ hash_u32(frame.seed + bounce * 0x68e31da4u));
    for (var attempt = 0u; attempt < 8u; attempt++) {
        let u1 = uniform3(pixel_key, stream, 2u * attempt);
        let u2 = uniform3(pixel_key, stream, 2u * attempt + 1u);
        let cos_theta = pow(1.0 - u1, 1.0 / (e + 1.0));
        let sin_theta = sqrt(max(0.0, 1.0 - cos_theta * cos_theta));
        let phi = 6.283185307 * u2;
        let dir = u * (cos(phi) * sin_theta) + v * (sin(phi) * sin_theta) + w * cos_theta;
        if dot(dir, n) > 0.0 {
            return dir;
        }
    }
    return w;
}

// Texture coordinates of object-space point p on a mesh triangle: the
// corners' coordinates weighted by p's barycentric coordinates (points off
// the triangle extrapolate linearly, which the footprint needs).
fn triangle_uv(tri: GpuTriangle, p: vec3<f32>) -> vec2<f32> {
    let e1 = tri.p1.xyz - tri.p0.xyz;
    let e2 = tri.p2.xyz - tri.p0.xyz;
    let r = p - tri.p0.xyz;
    let d11 = dot(e1, e1);
    let d12 = dot(e1, e2);
    let d22 = dot(e2, e2);
    let r1 = dot(r, e1);
    let r2 = dot(r, e2);
    let den = d11 * d22 - d12 * d12;
    if den == 0.0 {
        return vec2<f32>(tri.p0.w, tri.n0.w);
    }
    let b1 = (d22 * r1 - d12 * r2) / den;
    let b2 = (d11 * r2 - d12 * r1) / den;
    return vec2<f32>(tri.p0.w, tri.n0.w) * (1.0 - b1 - b2) + vec2<f32>(tri.p1.w, tri.n1.w) * b1
        + vec2<f32>(tri.p2.w, tri.n2.w) * b2;
}

// The mesh's own map at a hit (NO_TEXTURE when the hit is not on a mesh
// triangle or the triangle has none).
fn mesh_map(hit: TraceHit) -> u32 {
    if load_shape(load_instance(hit.instance).shape).kind != SHAPE_MESH {
        return NO_TEXTURE;
    }
    return triangle_maps[hit_triangle];
}

// The base colour at a traced hit at world point p (outward normal in
// hit.normal). The mip level comes from the footprint: the texture
// coordinates at p + e1 and p + e2 (world offsets on the tangent plane:
// where the neighbouring pixels' rays meet it for primary rays, the ray
// cone's axes for reflected ones), the larger step deciding, as raster
// derivatives do per pixel.
fn traced_albedo(hit: TraceHit, m: GpuMaterial, p: vec3<f32>, e1: vec3<f32>, e2: vec3<f32>) -> vec3<f32> {
    let inst = hit.instance;
    let to_object = load_instance(inst).object_from_world;
    let po = (to_object * vec4<f32>(p, 1.0)).xyz;
    if m.checker_size > 0.0 {
        return checker(m, po);
    }
    let no = (transpose(load_instance(inst).world_from_object) * vec4<f32>(hit.normal, 0.0)).xyz;
    let q1 = (to_object * vec4<f32>(p + e1, 1.0)).xyz;
    let q2 = (to_object * vec4<f32>(p + e2, 1.0)).xyz;
    let shape = load_shape(load_instance(inst).shape);
    var uv0: vec2<f32>;
    var uv1: vec2<f32>;
    var uv2: vec2<f32>;
    var periodic = false;
    if shape.kind == SHAPE_MESH {
        let tri = triangles[hit_triangle];
        uv0 = triangle_uv(tri, po);
        uv1 = triangle_uv(tri, q1);
        uv2 = triangle_uv(tri, q2);
    } else {
        uv0 = analytic_uv(shape.kind, shape.params, po, no);
        uv1 = analytic_uv(shape.kind, shape.params, q1, no);
        uv2 = analytic_uv(shape.kind, shape.params, q2, no);
        periodic = periodic_u(shape.kind, no);
    }
    let lod = footprint_lod(wrap_du(uv1 - uv0, periodic) * m.uv_scale, wrap_du(uv2 - uv0, periodic) * m.uv_scale);
    if m.texture_layer != NO_TEXTURE {
        return sample_map_level(m.texture_layer, m.texture_nearest != 0u, uv0 * m.uv_scale, lod);
    }
    return sample_map(triangle_maps[hit_triangle], uv0 * m.uv_scale, lod);
}

// Where the ray (o, dn) meets the tangent plane at p with normal n, as an
// offset from p (primary-ray differentials).
fn plane_offset(o: vec3<f32>, dn: vec3<f32>, p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let den = dot(dn, n);
    if abs(den) < 1e-6 {
        return vec3<f32>(0.0);
    }
    return o + dn * (dot(p - o, n) / den) - p;
}

// The ray cone's footprint axes at a hit: `width` across the ray, stretched
// by 1 / cos along the ray's projection on the surface.
fn cone_axes(d: vec3<f32>, n: vec3<f32>, width: f32) -> array<vec3<f32>, 2> {
    let cos_t = max(abs(dot(d, n)), 0.05);
    var along = d - n * dot(d, n);
    if dot(along, along) < 1e-12 {
        along = select(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), abs(n.x) > 0.9);
        along = along - n * dot(along, n);
    }
    along = normalize(along);
    return array<vec3<f32>, 2>(along * (width / cos_t), cross(n, along) * width);
}

@compute @workgroup_size(TRACE_WORKGROUP, TRACE_WORKGROUP)
fn main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    // Workgroup w of a dispatch of n shades tiles w, w + n, w + 2n, ...
    // (row-major). A GPU gets one workgroup per tile (a grid of the
    // tiles: one pass of the loop, the workgroup's own tile). The CPU
    // driver gets a few (render::trace): it starts every workgroup at a
    // cost (a kernel hashing and writing one word a pixel at 1280 x 720:
    // 6.8 ms as 14,400 workgroups, 1.7 ms as 2 that loop;
    // docs/performance.md), and each of its threads takes a contiguous
    // run of the workgroups, so each gets every n-th tile of the whole
    // image. One call of trace_tile: the driver inlines every call, and
    // the kernel's compile time grows with each copy.
    let tiles = (frame.size_px + vec2<u32>(TRACE_WORKGROUP - 1u)) / TRACE_WORKGROUP;
    let count = tiles.x * tiles.y;
    let stride = groups.x * groups.y;
    for (var t = wg.y * groups.x + wg.x; t < count; t += stride) {
        trace_tile(vec2<u32>(t % tiles.x, t / tiles.x), li);
    }
}

// One invocation's pixel of `tile`.
fn trace_tile(tile: vec2<u32>, li: u32) {
    // The CPU driver runs 8 consecutive invocations as one program, and a
    // branch or loop costs all 8 whenever one of them needs it. Each 8 is
    // laid out as a 4 x 2 block of pixels rather than a row of 8, so their
    // rays stay closer together and agree more often (TRACE_WORKGROUP / 4
    // blocks a row; docs/performance-history.md has the figures).
    let group = li / 8u;
    let lane = li % 8u;
    let blocks_per_row = TRACE_WORKGROUP / 4u;
    let local = vec2<u32>(4u * (group % blocks_per_row) + lane % 4u, 2u * (group / blocks_per_row) + lane / 4u);
    // Invocations past the image's edge trace its last row or column again
    // and write nothing: every invocation makes each trace call together
    // (trace_converged and trace_masked, lib/trace_bvh.wgsl), which the
    // packet walk needs.
    let inside = all(tile * TRACE_WORKGROUP + local < frame.size_px);
    let gid = min(tile * TRACE_WORKGROUP + local, frame.size_px - 1u);
    steps_left = MAX_INVOCATION_STEPS;
    overflowed = false;
    let pixel = vec2<i32>(gid.xy);
    let size = vec2<f32>(frame.size_px);
    // The pixel centre in NDC, unprojected through the same (jittered)
    // matrix the rasterizer used: the same primary ray.
    let ndc = vec2<f32>((f32(gid.x) + 0.5) / size.x * 2.0 - 1.0, 1.0 - (f32(gid.y) + 0.5) / size.y * 2.0);
    let near = frame.world_from_clip * vec4<f32>(ndc, 0.0, 1.0);
    let far = frame.world_from_clip * vec4<f32>(ndc, 1.0, 1.0);
    var o = near.xyz / near.w;
    var d = normalize(far.xyz / far.w - o);
    let eye = frame.eye_in_world.xyz;
    let forward = frame.view_forward.xyz;

    // The ray cone for mip selection: its spread is the angle between
    // neighbouring pixels' rays; reflections widen it by the roughness.
    // Primary hits use the neighbouring pixels' rays (ray differentials).
    var cone_spread = 0.0;
    var cone_width = 0.0;
    var d_dx = d;
    var d_dy = d;
    if TEXTURES_ENABLED {
        // The other pixel of this pixel's 2x2 quad in x and in y: the pair
        // the raster pass's fine derivatives difference.
        let step_x = select(2.0, -2.0, (gid.x & 1u) == 1u) / size.x;
        let step_y = select(2.0, -2.0, (gid.y & 1u) == 1u) / size.y;
        let far_dx = frame.world_from_clip * vec4<f32>(ndc + vec2<f32>(step_x, 0.0), 1.0, 1.0);
        let far_dy = frame.world_from_clip * vec4<f32>(ndc - vec2<f32>(0.0, step_y), 1.0, 1.0);
        d_dx = normalize(far_dx.xyz / far_dx.w - o);
        d_dy = normalize(far_dy.xyz / far_dy.w - o);
        cone_spread = length(d_dx - d);
    }
    let primary_o = o;
    var from_raster = false;

    let hybrid = frame.mode == RENDER_MODE_HYBRID;
    var hit: TraceHit;
    var raster_may_show = true;
    var accumulates = false;
    // Whether the tile's primary hits cast no shadow ray (TILE_UNSHADOWED:
    // the CPU proved every one culled or meeting nothing).
    var unshadowed = false;
    // Whether this pixel's normal, depth and id are stored: everywhere
    // unless the tile's word says no pass reads them this sample.
    var stores_gbuffer = true;
    if PRIMARY_TILES {
        // The workgroup's tile: every invocation of it takes the same path.
        let tiles = (frame.size_px + vec2<u32>(TRACE_WORKGROUP - 1u)) / TRACE_WORKGROUP;
        let tiles_x = tiles.x;
        let r = (tile.y * tiles_x + tile.x) * PRIMARY_TILE_WORDS;
        let flags = primary_tiles[tiles.x * tiles.y * PRIMARY_TILE_WORDS + tile.y * tiles_x + tile.x];
        stores_gbuffer = (flags & TILE_GBUFFER_SKIPS) == 0u;
        if frame.gbuffer_only != 0u {
            if stores_gbuffer {
                // Completing the last sample's G-buffer: that sample
                // stored this tile's texels already.
                return;
            }
            stores_gbuffer = true;
        }
        raster_may_show = (flags & TILE_MESH_MAY_SHOW) != 0u;
        accumulates = (flags & TILE_TRACE_ACCUMULATES) != 0u;
        unshadowed = (flags & TILE_UNSHADOWED) != 0u;
        // A record of at most one instance is read from its summary.
        let summary = flags >> TILE_RECORD_SHIFT;
        var listed = true;
        if summary != TILE_RECORD_READ {
            hit = trace_summary(summary, o, d, hybrid);
        } else {
            listed = primary_tiles[r] != PRIMARY_TILE_WALK;
            if listed {
                hit = trace_listed(r, o, d, hybrid);
            }
        }
        let walked = trace_masked(!listed, o, d, 0.0, 3.0e38, hybrid, false);
        if !listed {
            hit = walked;
        }
    } else {
        hit = trace_converged(o, d, 0.0, 3.0e38, hybrid, false);
    }
    // Where no mesh can show, the whole workgroup skips the raster reads.
    if hybrid && raster_may_show {
        let id = textureLoad(raster_id, pixel, 0).x;
        if id != 0u {
            let nd = textureLoad(raster_normal_depth, pixel, 0);
            let t_raster = (nd.w - dot(o - eye, forward)) / dot(d, forward);
            if t_raster < hit.t {
                // The raster normal already faces the viewer.
                hit = TraceHit(t_raster, id - 1u, nd.xyz, nd.xyz, load_instance(id - 1u).material);
                from_raster = true;
            }
        }
    }

    var primary_normal = vec3<f32>(0.0);
    var primary_depth = FAR_DEPTH;
    var primary_id = 0u;
    if hit.instance != NO_HIT {
        let p = o + d * hit.t;
        primary_normal = facing_normal(hit, d);
        primary_depth = dot(p - eye, forward);
        primary_id = hit.instance + 1u;
    }
    if frame.gbuffer_only != 0u {
        // Completing the last sample's G-buffer: no shading, no colour.
        if inside {
            let k = traced_index(gid.xy, frame.size_px.x);
            out_normal_depth[k] = vec4<f32>(primary_normal, primary_depth);
            out_id[k] = primary_id;
        }
        return;
    }

    // Mirror reflections: each bounce keeps (1 - reflectivity) of its own
    // shading and passes the rest on to the reflected ray.
    // `going`: this pixel's ray goes on (it hit something, and every surface
    // so far reflects). The invocations go round the loop together while any
    // one's ray goes on, so that they trace the shadow and reflection rays
    // together (trace_masked), those whose ray has ended asking for none.
    var colour = vec3<f32>(0.0);
    var weight = 1.0;
    var going = true;
    for (var bounce = 0u; bounce <= frame.max_bounces; bounce++) {
        if going && hit.instance == NO_HIT {
            colour += weight * frame.background.rgb;
            going = false;
        }
        if !any_lane(going) {
            break;
        }
        let p = o + d * hit.t;
        let n = facing_normal(hit, d);
        var m = load_material(hit.material);
        if TEXTURES_ENABLED {
            cone_width += cone_spread * hit.t;
            if from_raster {
                m.base_color = textureLoad(raster_albedo, pixel, 0).rgb;
            } else if has_base_color_map(m) || mesh_map(hit) != NO_TEXTURE {
                var axes = cone_axes(d, n, cone_width);
                if bounce == 0u {
                    // On the surface's own plane (the geometric normal), where
                    // the raster pass's neighbouring fragments lie.
                    axes[0] = plane_offset(primary_o, d_dx, p, hit.geometric);
                    axes[1] = plane_offset(primary_o, d_dy, p, hit.geometric);
                }
                m.base_color = traced_albedo(hit, m, p, axes[0], axes[1]);
            }
            from_raster = false;
            cone_spread += m.roughness;
        }
        var reflectivity = m.reflectivity;
        if !REFLECTIONS_ENABLED || bounce == frame.max_bounces {
            reflectivity = 0.0;
        }
        // The instance whose outside the shadow rays leave (none when the
        // ray hit a surface from behind).
        let leaving = select(NO_HIT, hit.instance, dot(hit.geometric, d) < 0.0);
        // A primary hit of a TILE_UNSHADOWED tile asks for no shadow ray
        // (shade_hit's `going` only lets its lanes cast them).
        let casts = going && !(bounce == 0u && unshadowed);
        let shaded = shade_hit(p, n, -d, m, hit.instance, leaving, casts);
        if going {
            colour += weight * (1.0 - reflectivity) * shaded;
        }
        going = going && reflectivity > 0.0;
        if !any_lane(going) {
            break;
        }
        weight *= reflectivity;
        o = p + n * frame.ray_epsilon;
        d = glossy_direction(reflect(d, n), n, m.roughness, gid.y * frame.size_px.x + gid.x, bounce);
        hit = trace_masked(going, o, d, 0.0, 3.0e38, false, false);
    }

    if !inside {
        return;
    }
    if overflowed {
        // Never silent: a loud colour in the image and a count for the tests.
        colour = vec3<f32>(1.0, 0.0, 1.0);
        atomicAdd(&stats[0], 1u);
    }
    let k = traced_index(gid.xy, frame.size_px.x);
    // The colour as the G-buffer holds it, so the sums are the same
    // whichever pass adds it.
    let halves = pack_color_halves(colour);
    if accumulates {
        add_sample(gid.xy, unpack_color_halves(halves));
    } else {
        out_color[k] = halves;
    }
    if stores_gbuffer {
        out_normal_depth[k] = vec4<f32>(primary_normal, primary_depth);
        out_id[k] = primary_id;
    }
}
