// Resolve pass: the accumulator's average, tone mapped and sRGB-encoded,
// drawn as one full-screen triangle into the display or capture target.

#include "lib/types.wgsl"
#include "lib/color.wgsl"

// Fixed per pipeline (src/render/resolve.rs), so only their code is in
// the shader: the tone map (TONE_MAP_*), and whether to encode sRGB (for
// targets whose format does not).
override TONE_MAP: u32 = TONE_MAP_CLAMP;
override ENCODE_SRGB: bool = false;

@group(0) @binding(0) var<uniform> params: ResolveUniforms;
@group(0) @binding(1) var<storage, read> accum: array<vec4<f32>>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let a = accum[u32(pos.y) * params.width + u32(pos.x)];
    let mean = a.rgb / max(a.w, 1.0);
    var c = tone_map(mean * params.exposure, TONE_MAP);
    if ENCODE_SRGB {
        c = srgb_encode(c);
    }
    return vec4<f32>(c, 1.0);
}
