// Accumulate pass: this sample's G-buffer colour, with toon outlines drawn
// from depth, normal and id discontinuities, added to the float accumulator.
// accum[p].w counts the samples, so resolve divides by it.

#include "lib/types.wgsl"

@group(0) @binding(0) var<uniform> frame: FrameUniforms;
@group(0) @binding(1) var<storage, read> instances: array<GpuInstance>;
@group(0) @binding(2) var<storage, read> materials: array<GpuMaterial>;
@group(0) @binding(3) var color_tex: texture_2d<f32>;
@group(0) @binding(4) var normal_depth_tex: texture_2d<f32>;
@group(0) @binding(5) var id_tex: texture_2d<u32>;
@group(0) @binding(6) var<storage, read_write> accum: array<vec4<f32>>;

const ACCUMULATE_WORKGROUP: u32 = 8u;
// q is in front of p when its view depth is smaller by this fraction.
const DEPTH_JUMP: f32 = 0.05;
// Normals more than 60 degrees apart make a crease.
const CREASE_COS: f32 = 0.5;

// The outline colour covering pixel p, if any (a = 1). An outline is drawn
// on the far side of a discontinuity: pixel p takes the outline of the
// nearest pixel q within q's material's width (in pixels: the width does
// not change with resolution) that is in front of p, or on p's background.
fn outline_at(p: vec2<i32>) -> vec4<f32> {
    let size = vec2<i32>(frame.size_px);
    let id_p = textureLoad(id_tex, p, 0).x;
    let nd_p = textureLoad(normal_depth_tex, p, 0);
    let r = i32(ceil(frame.max_outline_px));
    var best_depth = 3.0e38;
    var result = vec4<f32>(0.0);
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            let q = p + vec2<i32>(dx, dy);
            if (dx == 0 && dy == 0) || any(q < vec2<i32>(0)) || any(q >= size) {
                continue;
            }
            let id_q = textureLoad(id_tex, q, 0).x;
            if id_q == 0u {
                continue;
            }
            let m = materials[instances[id_q - 1u].material];
            if f32(dx * dx + dy * dy) > m.outline_width_px * m.outline_width_px {
                continue;
            }
            let nd_q = textureLoad(normal_depth_tex, q, 0);
            var edge = id_p == 0u;
            if !edge {
                let in_front = nd_q.w < nd_p.w * (1.0 - DEPTH_JUMP);
                let other_object = id_q != id_p && nd_q.w < nd_p.w;
                let crease = dot(nd_q.xyz, nd_p.xyz) < CREASE_COS && nd_q.w <= nd_p.w;
                edge = in_front || other_object || crease;
            }
            if edge && nd_q.w < best_depth {
                best_depth = nd_q.w;
                result = vec4<f32>(m.outline_color, 1.0);
            }
        }
    }
    return result;
}

@compute @workgroup_size(ACCUMULATE_WORKGROUP, ACCUMULATE_WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= frame.size_px.x || gid.y >= frame.size_px.y {
        return;
    }
    let p = vec2<i32>(gid.xy);
    var c = textureLoad(color_tex, p, 0).rgb;
    if frame.max_outline_px > 0.0 {
        let o = outline_at(p);
        c = mix(c, o.rgb, o.a);
    }
    let i = gid.y * frame.size_px.x + gid.x;
    if frame.sample_index == 0u {
        accum[i] = vec4<f32>(c, 1.0);
    } else {
        accum[i] += vec4<f32>(c, 1.0);
    }
}
