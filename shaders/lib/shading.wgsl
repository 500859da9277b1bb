// Blinn-Phong and toon shading: written once, used by the raster fragment
// shader and by the compute passes alike, so every path shades the same.

// What the scene's materials and lights use, fixed per pipeline (the raster
// and trace pipelines are keyed by it, src/render/scene_buffers.rs
// ShadingVariant), so the code of what no material or light uses is not in
// the kernel: the CPU driver pays for code that any of 8 neighbouring
// invocations might need (Mesa 22.3: all of it). Pipelines that do not set
// them hold everything. SHADING_MODELS: bit 0 Blinn-Phong, bit 1 toon.
// LIGHT_KINDS: bit 0 directional, bit 1 point.
override SHADING_MODELS: u32 = 3u;
override LIGHT_KINDS: u32 = 3u;

fn is_toon(m: GpuMaterial) -> bool {
    if SHADING_MODELS == 2u {
        return true;
    }
    if SHADING_MODELS == 1u {
        return false;
    }
    return m.model == SHADING_TOON;
}

// The raster pipelines fix the number of lights and each light's kind
// (src/render/raster.rs, LightLayout) when a scene has at most 8: the
// fragment shader's loop over the lights then unrolls, and each light runs
// only its own kind's code. On the CPU driver the loop over
// frame.light_count, a count the compiler does not know, cost about a
// third of the default scene's raster pass (docs/performance-history.md).
// LIGHT_COUNT is LIGHTS_DYNAMIC (the default, and the trace kernel's) when
// the count is left to frame.light_count; POINT_LIGHTS: bit i set when
// light i is a point light.
override LIGHT_COUNT: u32 = LIGHTS_DYNAMIC;
override POINT_LIGHTS: u32 = 0u;

// How many lights a light loop visits: LIGHT_COUNT when fixed, else
// `frame_count` (frame.light_count).
fn light_loop_count(frame_count: u32) -> u32 {
    if LIGHT_COUNT != LIGHTS_DYNAMIC {
        return LIGHT_COUNT;
    }
    return frame_count;
}

// Whether light i (the light itself: `light`) is directional.
fn is_directional(i: u32, light: GpuLight) -> bool {
    if LIGHT_COUNT != LIGHTS_DYNAMIC {
        return ((POINT_LIGHTS >> i) & 1u) == 0u;
    }
    if LIGHT_KINDS == 1u {
        return true;
    }
    if LIGHT_KINDS == 2u {
        return false;
    }
    return light.position_or_direction.w == 0.0;
}

// The direction towards a light from p, and the radiance arriving there.
struct LightSample {
    to_light: vec3<f32>,
    radiance: vec3<f32>,
    distance: f32,
}

// Directional lights arrive undiminished; point lights fall off as 1/d^2.
// `light` is light i.
fn sample_light(i: u32, light: GpuLight, p: vec3<f32>) -> LightSample {
    var s: LightSample;
    if is_directional(i, light) {
        // Unit length already (light_to_gpu normalizes it once): on the
        // CPU driver a normalize here costs every pixel and light.
        s.to_light = -light.position_or_direction.xyz;
        s.radiance = light.radiance.rgb;
        s.distance = 3.0e38;
    } else {
        let d = light.position_or_direction.xyz - p;
        s.distance = length(d);
        s.to_light = d / s.distance;
        s.radiance = light.radiance.rgb / (s.distance * s.distance);
    }
    return s;
}

// How many of a material's four vec4s of toon thresholds any material of
// the scene fills (1 to 4), fixed per pipeline: the slots beyond hold 2.0
// and count nothing, so leaving them out changes no band, and the CPU
// driver neither loads nor compares them (each field of a material is a
// gather per pixel there). Pipelines that do not set it read all four.
override TOON_THRESHOLD_VECS: u32 = 4u;

// The toon band of a diffuse term d = max(N.L, 0): the number of thresholds
// at or below d, so band 0 holds the unlit side and the darkest lit band.
// Unused threshold slots hold 2.0, which d never reaches; counting with
// vector steps avoids a dynamically indexed loop (slow on CPU drivers).
fn toon_band(m: GpuMaterial, d: f32) -> u32 {
    let dv = vec4<f32>(d);
    let ones = vec4<f32>(1.0);
    var count = dot(step(m.thresholds[0], dv), ones);
    if TOON_THRESHOLD_VECS > 1u {
        count += dot(step(m.thresholds[1], dv), ones);
    }
    if TOON_THRESHOLD_VECS > 2u {
        count += dot(step(m.thresholds[2], dv), ones);
    }
    if TOON_THRESHOLD_VECS > 3u {
        count += dot(step(m.thresholds[3], dv), ones);
    }
    return u32(count);
}

// Band b of N shows the diffuse level (b + 1) / N: N flat levels, the top
// one full strength.
fn toon_level(m: GpuMaterial, d: f32) -> f32 {
    return f32(toon_band(m, d) + 1u) / f32(m.band_count);
}

// One light's contribution at a point with unit normal n, unit direction to
// the viewer v, unit direction to the light l.
// Blinn-Phong: kd * max(N.L, 0) + ks * max(N.H, 0)^shininess (the specular
// term only where N.L > 0). Toon: the same two terms thresholded.
fn shade_light(m: GpuMaterial, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, radiance: vec3<f32>) -> vec3<f32> {
    let n_dot_l = dot(n, l);
    let h = normalize(l + v);
    if is_toon(m) {
        let diffuse = toon_level(m, max(n_dot_l, 0.0));
        // (N.H)^shininess > specular_threshold, tested as N.H > its
        // shininess-th root (pow is monotonic on N.H >= 0): a pow per
        // pixel and light costs the CPU driver about a tenth of the
        // default scene's raster pass (docs/performance-history.md).
        let highlight = select(0.0, 1.0, n_dot_l > 0.0 && dot(n, h) > m.highlight_cos);
        return (m.base_color * diffuse + m.specular_color * highlight) * radiance;
    }
    let spec = select(0.0, pow(max(dot(n, h), 0.0), m.shininess), n_dot_l > 0.0);
    return (m.base_color * max(n_dot_l, 0.0) + m.specular_color * spec) * radiance;
}

// A light's contribution where it is blocked: what shade_light gives a
// surface facing away from it (toon: the darkest band; Blinn-Phong: none),
// so a cast shadow looks like the unlit side.
fn shade_light_blocked(m: GpuMaterial, radiance: vec3<f32>) -> vec3<f32> {
    if is_toon(m) {
        return m.base_color * toon_level(m, 0.0) * radiance;
    }
    return vec3<f32>(0.0);
}

// The light-independent part: ambient * kd, plus the toon rim light.
fn shade_ambient(m: GpuMaterial, n: vec3<f32>, v: vec3<f32>, ambient: vec3<f32>) -> vec3<f32> {
    var c = ambient * m.base_color;
    if is_toon(m) && 1.0 - max(dot(n, v), 0.0) > m.rim_threshold {
        c += m.rim_color;
    }
    return c;
}
