// The floor kernel of `celray bench`: about the least work a ray tracer can
// do per pixel. One primary ray and, where it hits, one shadow ray towards a
// directional light, both tested by brute force against every sphere (no
// BVH, no instances, no materials), and a Lambert colour written out. Every
// trace figure of the bench is also given as a ratio to this kernel's time
// in the same run, so figures taken on different or busy machines compare.

struct FloorParams {
    size_px: vec2<u32>,
    sphere_count: u32,
    tan_half_fov: f32,
}

@group(0) @binding(0) var<uniform> params: FloorParams;
// xyz: centre, w: radius.
@group(0) @binding(1) var<storage, read> spheres: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> out_rgba8: array<u32>;

// The nearest t in (1e-4, t_max) where o + t d meets sphere s, else t_max.
fn hit_sphere(o: vec3<f32>, d: vec3<f32>, s: vec4<f32>, t_max: f32) -> f32 {
    let oc = o - s.xyz;
    let b = dot(oc, d);
    let c = dot(oc, oc) - s.w * s.w;
    let disc = b * b - c;
    if disc < 0.0 {
        return t_max;
    }
    let r = sqrt(disc);
    var t = -b - r;
    if t <= 1e-4 {
        t = -b + r;
    }
    return select(t_max, t, t > 1e-4 && t < t_max);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.size_px.x || gid.y >= params.size_px.y {
        return;
    }
    let size = vec2<f32>(params.size_px);
    let ndc = (vec2<f32>(gid.xy) + 0.5) / size * 2.0 - 1.0;
    let aspect = size.x / size.y;
    let o = vec3<f32>(0.0, 0.0, 5.0);
    let d = normalize(vec3<f32>(ndc.x * aspect * params.tan_half_fov, -ndc.y * params.tan_half_fov, -1.0));
    var t = 3.0e38;
    var nearest = 0u;
    for (var i = 0u; i < params.sphere_count; i++) {
        let ti = hit_sphere(o, d, spheres[i], t);
        if ti < t {
            t = ti;
            nearest = i;
        }
    }
    var colour = vec3<f32>(0.6, 0.7, 0.85);
    if t < 3.0e38 {
        let p = o + t * d;
        let n = normalize(p - spheres[nearest].xyz);
        let to_light = normalize(vec3<f32>(0.4, 1.0, 0.5));
        var lit = max(dot(n, to_light), 0.0);
        if lit > 0.0 {
            let so = p + n * 1e-3;
            for (var i = 0u; i < params.sphere_count; i++) {
                if hit_sphere(so, to_light, spheres[i], 3.0e38) < 3.0e38 {
                    lit = 0.0;
                    break;
                }
            }
        }
        colour = vec3<f32>(0.8, 0.3, 0.2) * (0.1 + 0.9 * lit);
    }
    out_rgba8[gid.y * params.size_px.x + gid.x] = pack4x8unorm(vec4<f32>(colour, 1.0));
}
