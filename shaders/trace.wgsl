// Trace pass: per pixel, the same primary ray the raster pass samples;
// analytic shapes (hybrid) or everything (raytrace) are traced through the
// two-level BVH and composited against the raster depth; then shadow rays
// and mirror reflections against the whole scene, shaded by the same
// functions as the raster pass. Writes the G-buffer the accumulate pass reads.

#include "lib/types.wgsl"
#include "lib/shading.wgsl"
#include "lib/intersect.wgsl"
#include "lib/traverse.wgsl"
#include "lib/csg.wgsl"
#include "lib/random.wgsl"

@group(0) @binding(0) var<uniform> frame: FrameUniforms;
@group(0) @binding(1) var<storage, read> instances: array<GpuInstance>;
@group(0) @binding(2) var<storage, read> materials: array<GpuMaterial>;
@group(0) @binding(3) var<storage, read> lights: array<GpuLight>;
@group(0) @binding(4) var<storage, read> shapes: array<GpuShape>;
@group(0) @binding(5) var<storage, read> nodes: array<BvhNode>;
@group(0) @binding(6) var<storage, read> triangles: array<GpuTriangle>;
@group(0) @binding(7) var<storage, read> tlas_items: array<u32>;
// [0]: pixels whose traversal ran out of its step budget.
@group(0) @binding(8) var<storage, read_write> stats: array<atomic<u32>>;
@group(0) @binding(9) var<storage, read> csg_ops: array<GpuCsgOp>;
@group(0) @binding(10) var<storage, read> csg_leaves: array<GpuCsgLeaf>;
@group(1) @binding(0) var raster_normal_depth: texture_2d<f32>;
@group(1) @binding(1) var raster_id: texture_2d<u32>;
@group(1) @binding(2) var out_color: texture_storage_2d<rgba16float, write>;
@group(1) @binding(3) var out_normal_depth: texture_storage_2d<rgba32float, write>;
@group(1) @binding(4) var out_id: texture_storage_2d<r32uint, write>;

const TRACE_WORKGROUP: u32 = 8u;
// Loop iterations one pixel may spend on traversal, all rays together:
// well under lavapipe's silent cut at ~65,535.
const MAX_INVOCATION_STEPS: u32 = 48000u;
// The far-plane depth written where no surface is hit.
const FAR_DEPTH: f32 = 65504.0;

// What the scene and settings can reach, fixed per pipeline so that code no
// pixel can need is not in the kernel at all (the CPU driver pays for code
// that 8 neighbouring invocations might need, and Mesa 22.3 for all of it).
// False only when it changes nothing: no light casts shadows; no material
// reflects (or max_bounces is 0); no reflective material is rough.
override SHADOWS_ENABLED: bool = true;
override REFLECTIONS_ENABLED: bool = true;
override GLOSSY_ENABLED: bool = true;

// The normal facing the ray: two-sided surfaces are shaded on both sides.
fn facing_normal(h: TraceHit, d: vec3<f32>) -> vec3<f32> {
    return select(h.normal, -h.normal, dot(h.geometric, d) > 0.0);
}

// Ambient, rim and every light, with a shadow ray per shadow-casting light.
fn shade_hit(p: vec3<f32>, n: vec3<f32>, v: vec3<f32>, m: GpuMaterial) -> vec3<f32> {
    var c = shade_ambient(m, n, v, frame.ambient.rgb);
    for (var i = 0u; i < frame.light_count; i++) {
        let light = lights[i];
        let ls = sample_light(light, p);
        var visible = true;
        if SHADOWS_ENABLED && light.radiance.w > 0.0 && dot(n, ls.to_light) > 0.0 {
            let origin = p + n * frame.ray_epsilon;
            visible = trace(origin, ls.to_light, 0.0, ls.distance, false, true).instance == NO_HIT;
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

@compute @workgroup_size(TRACE_WORKGROUP, TRACE_WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= frame.size_px.x || gid.y >= frame.size_px.y {
        return;
    }
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

    let hybrid = frame.mode == RENDER_MODE_HYBRID;
    var hit = trace(o, d, 0.0, 3.0e38, hybrid, false);
    if hybrid {
        let id = textureLoad(raster_id, pixel, 0).x;
        if id != 0u {
            let nd = textureLoad(raster_normal_depth, pixel, 0);
            let t_raster = (nd.w - dot(o - eye, forward)) / dot(d, forward);
            if t_raster < hit.t {
                // The raster normal already faces the viewer.
                hit = TraceHit(t_raster, id - 1u, nd.xyz, nd.xyz, instances[id - 1u].material);
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

    // Mirror reflections: each bounce keeps (1 - reflectivity) of its own
    // shading and passes the rest on to the reflected ray.
    var colour = vec3<f32>(0.0);
    var weight = 1.0;
    for (var bounce = 0u; bounce <= frame.max_bounces; bounce++) {
        if hit.instance == NO_HIT {
            colour += weight * frame.background.rgb;
            break;
        }
        let p = o + d * hit.t;
        let n = facing_normal(hit, d);
        let m = materials[hit.material];
        var reflectivity = m.reflectivity;
        if !REFLECTIONS_ENABLED || bounce == frame.max_bounces {
            reflectivity = 0.0;
        }
        colour += weight * (1.0 - reflectivity) * shade_hit(p, n, -d, m);
        if reflectivity <= 0.0 {
            break;
        }
        weight *= reflectivity;
        o = p + n * frame.ray_epsilon;
        d = glossy_direction(reflect(d, n), n, m.roughness, gid.y * frame.size_px.x + gid.x, bounce);
        hit = trace(o, d, 0.0, 3.0e38, false, false);
    }

    if overflowed {
        // Never silent: a loud colour in the image and a count for the tests.
        colour = vec3<f32>(1.0, 0.0, 1.0);
        atomicAdd(&stats[0], 1u);
    }
    textureStore(out_color, pixel, vec4<f32>(colour, 1.0));
    textureStore(out_normal_depth, pixel, vec4<f32>(primary_normal, primary_depth));
    textureStore(out_id, pixel, vec4<u32>(primary_id, 0u, 0u, 0u));
}
