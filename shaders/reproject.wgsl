// Reproject pass (temporal accumulation while the view moves): blends this
// frame's sample, already in the accumulator with its outlines, into the
// previous frame's image fetched where this pixel's surface point was.
//
// Per pixel: the visible point is rebuilt from the G-buffer's view depth
// along this sample's primary ray; projecting it with this frame's and the
// previous frame's unjittered matrices gives the motion vector (pixels). The
// history is read there with a Catmull-Rom filter, rejected where the
// previous frame saw another object or another depth there (disocclusion),
// clipped towards this frame's 3x3 neighbourhood (variance clipping in YCoCg),
// and blended with weight 1 / (samples the history holds + 1).
//
// Storage layout of the accumulator and the history alike: rgb = colour sum,
// w = how many samples that sum holds; the resolve pass divides.

#include "lib/types.wgsl"

struct ReprojectUniforms {
    // This frame's camera without jitter or lens offset.
    cur_clip_from_world: mat4x4<f32>,
    // The previous frame's camera without jitter or lens offset.
    prev_clip_from_world: mat4x4<f32>,
    prev_eye: vec4<f32>,
    // Unit forward of the previous camera: its view depth of p is
    // dot(p - prev_eye, prev_forward), as the G-buffer stores it.
    prev_forward: vec4<f32>,
    // The most samples a history may count while the view moves.
    max_history: f32,
    // Half-width of the clipping box in standard deviations.
    clip_gamma: f32,
    // Relative view-depth difference beyond which the history is rejected.
    depth_tolerance: f32,
    // TEMPORAL_REJECT_* : whether to reject and clip, or blend blindly.
    rejection: u32,

}

const TEMPORAL_REJECT_NONE: u32 = 0u;
const TEMPORAL_REJECT_CLIP: u32 = 1u;
// REPROJECT_WORKGROUP: lib/limits.wgsl (generated).
// An outline pixel takes the motion of an object at most this far away.
const MAX_DILATION: i32 = 2;
// Smallest half-width of the clipping box (a flat neighbourhood).
const CLIP_FLOOR: f32 = 1e-5;
// DEPTH_JUMP (lib/limits.wgsl): q is in front of p when its view depth is
// smaller by this fraction, as for the accumulate pass's outlines.

@group(0) @binding(0) var<uniform> frame: FrameUniforms;
@group(0) @binding(1) var<uniform> params: ReprojectUniforms;
@group(0) @binding(2) var normal_depth_tex: texture_2d<f32>;
@group(0) @binding(3) var id_tex: texture_2d<u32>;
@group(0) @binding(4) var<storage, read> current: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> history: array<vec4<f32>>;
@group(0) @binding(6) var history_normal_depth: texture_2d<f32>;
@group(0) @binding(7) var history_id: texture_2d<u32>;
@group(0) @binding(8) var<storage, read_write> blended: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> motion: array<vec2<f32>>;

fn to_pixel(clip: vec4<f32>) -> vec2<f32> {
    let ndc = clip.xy / clip.w;
    let size = vec2<f32>(frame.size_px);
    return vec2<f32>((ndc.x + 1.0) * 0.5 * size.x, (1.0 - ndc.y) * 0.5 * size.y);
}

fn rgb_to_ycocg(c: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        0.25 * c.r + 0.5 * c.g + 0.25 * c.b,
        0.5 * c.r - 0.5 * c.b,
        -0.25 * c.r + 0.5 * c.g - 0.25 * c.b,
    );
}

fn ycocg_to_rgb(c: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(c.x + c.y - c.z, c.x + c.z, c.x - c.y - c.z);
}

fn index_of(q: vec2<i32>) -> u32 {
    let c = clamp(q, vec2<i32>(0), vec2<i32>(frame.size_px) - 1);
    return u32(c.y) * frame.size_px.x + u32(c.x);
}

// The average colour a sum holds.
fn average(s: vec4<f32>) -> vec3<f32> {
    return s.rgb / max(s.w, 1e-6);
}

// The history's average colour at pixel position pos (pixel centres at
// i + 0.5), Catmull-Rom filtered over 4 x 4 texels, edges clamped.
fn history_catmull_rom(pos: vec2<f32>) -> vec3<f32> {
    let t = pos - 0.5;
    let b = floor(t);
    let f = t - b;
    let w0 = f * (-0.5 + f * (1.0 - 0.5 * f));
    let w1 = 1.0 + f * f * (-2.5 + 1.5 * f);
    let w2 = f * (0.5 + f * (2.0 - 1.5 * f));
    let w3 = f * f * (-0.5 + 0.5 * f);
    let wx = array<f32, 4>(w0.x, w1.x, w2.x, w3.x);
    let wy = array<f32, 4>(w0.y, w1.y, w2.y, w3.y);
    let origin = vec2<i32>(b) - 1;
    var sum = vec3<f32>(0.0);
    for (var j = 0; j < 4; j++) {
        var row = vec3<f32>(0.0);
        for (var i = 0; i < 4; i++) {
            row += wx[i] * average(history[index_of(origin + vec2<i32>(i, j))]);
        }
        sum += wy[j] * row;
    }
    // The negative lobes overshoot next to edges: keep the result within
    // the 2 x 2 texels around pos (what bilinear filtering could give).
    let t00 = average(history[index_of(vec2<i32>(b))]);
    let t10 = average(history[index_of(vec2<i32>(b) + vec2<i32>(1, 0))]);
    let t01 = average(history[index_of(vec2<i32>(b) + vec2<i32>(0, 1))]);
    let t11 = average(history[index_of(vec2<i32>(b) + vec2<i32>(1, 1))]);
    return clamp(sum, min(min(t00, t10), min(t01, t11)), max(max(t00, t10), max(t01, t11)));
}

// Whether the previous frame saw this surface near pos: a texel of the
// 2 x 2 around it (or, for a pixel that takes the motion of an outline's
// object, of the square of `radius` around it) has the same object id and
// (for objects) a view depth within the tolerance of the one this point
// had from the previous camera.
fn history_matches(pos: vec2<f32>, id: u32, prev_depth: f32, radius: i32) -> bool {
    let size = vec2<f32>(frame.size_px);
    if any(pos < vec2<f32>(0.0)) || any(pos > size) {
        return false;
    }
    var lo = vec2<i32>(floor(pos - 0.5));
    var hi = lo + 1;
    if radius > 0 {
        lo = vec2<i32>(floor(pos)) - radius;
        hi = vec2<i32>(floor(pos)) + radius;
    }
    lo = max(lo, vec2<i32>(0));
    hi = min(hi, vec2<i32>(frame.size_px) - 1);
    var found = false;
    for (var y = lo.y; y <= hi.y; y++) {
        for (var x = lo.x; x <= hi.x; x++) {
            let q = vec2<i32>(x, y);
            if textureLoad(history_id, q, 0).x == id {
                if id == 0u {
                    found = true;
                } else {
                    let d = textureLoad(history_normal_depth, q, 0).w;
                    found = found || abs(d - prev_depth) <= params.depth_tolerance * prev_depth;
                }
            }
        }
    }
    return found;
}

// The surface point pixel q's sample sees: on this sample's primary ray
// through q's centre (as the trace pass unprojects it), at the G-buffer's
// view depth; the background is a point at infinity along the ray (w = 0).
fn visible_point(q: vec2<i32>, id: u32, depth: f32) -> vec4<f32> {
    let size = vec2<f32>(frame.size_px);
    let ndc = vec2<f32>(
        (f32(q.x) + 0.5) / size.x * 2.0 - 1.0,
        1.0 - (f32(q.y) + 0.5) / size.y * 2.0,
    );
    let a_h = frame.world_from_clip * vec4<f32>(ndc, 0.0, 1.0);
    let b_h = frame.world_from_clip * vec4<f32>(ndc, 0.5, 1.0);
    let a = a_h.xyz / a_h.w;
    let dir = b_h.xyz / b_h.w - a;
    if id == 0u {
        return vec4<f32>(dir, 0.0);
    }
    let forward = frame.view_forward.xyz;
    let t = (depth - dot(a - frame.eye_in_world.xyz, forward)) / dot(dir, forward);
    return vec4<f32>(a + dir * t, 1.0);
}

fn motion_of(point: vec4<f32>) -> vec2<f32> {
    return to_pixel(params.cur_clip_from_world * point)
        - to_pixel(params.prev_clip_from_world * point);
}

// Moves h towards the box centre until it lies in the box (Salvi's clip):
// unlike a per-channel clamp, it keeps the hue of the direction it came from.
fn clip_to_box(h: vec3<f32>, centre: vec3<f32>, extent: vec3<f32>) -> vec3<f32> {
    let v = h - centre;
    let a = abs(v / max(extent, vec3<f32>(CLIP_FLOOR)));
    let m = max(a.x, max(a.y, a.z));
    if m > 1.0 {
        return centre + v / m;
    }
    return h;
}

@compute @workgroup_size(REPROJECT_WORKGROUP, REPROJECT_WORKGROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= frame.size_px.x || gid.y >= frame.size_px.y {
        return;
    }
    let p = vec2<i32>(gid.xy);
    let i = gid.y * frame.size_px.x + gid.x;
    let id = textureLoad(id_tex, p, 0).x;
    let depth = textureLoad(normal_depth_tex, p, 0).w;
    let point = visible_point(p, id, depth);
    motion[i] = motion_of(point);

    // Outlines are drawn on the far side of an edge, so the pixels of an
    // outline belong to the surface behind; they move with the object in
    // front. Such pixels (an object nearer by the outline depth jump within
    // the outline radius) take that object's point, motion and id.
    let r = clamp(i32(ceil(frame.max_outline_px)), 0, MAX_DILATION);
    var own_depth = 3.0e38;
    if id != 0u {
        own_depth = depth;
    }
    var front = p;
    var front_id = id;
    var front_depth = own_depth * (1.0 - DEPTH_JUMP);
    for (var dy = -r; dy <= r; dy++) {
        for (var dx = -r; dx <= r; dx++) {
            // Within the outline disk only (a 1.5-pixel outline reads 3 x 3).
            if f32(dx * dx + dy * dy) > frame.max_outline_px * frame.max_outline_px {
                continue;
            }
            let q = clamp(p + vec2<i32>(dx, dy), vec2<i32>(0), vec2<i32>(frame.size_px) - 1);
            let id_q = textureLoad(id_tex, q, 0).x;
            if id_q != 0u {
                let d = textureLoad(normal_depth_tex, q, 0).w;
                if d < front_depth {
                    front = q;
                    front_id = id_q;
                    front_depth = d;
                }
            }
        }
    }
    var dilated = 0;
    var mv = motion[i];
    var prev_depth = 0.0;
    var surface = point;
    if any(front != p) {
        dilated = r;
        surface = visible_point(front, front_id, front_depth);
        mv = motion_of(surface);
    }
    if front_id != 0u {
        prev_depth = dot(surface.xyz - params.prev_eye.xyz, params.prev_forward.xyz);
    }

    let c = average(current[i]);
    let pos = vec2<f32>(gid.xy) + 0.5 - mv;
    var hist = history_catmull_rom(pos);
    var n_hist = min(history[index_of(vec2<i32>(floor(pos)))].w, params.max_history);
    if params.rejection == TEMPORAL_REJECT_CLIP {
        if history_matches(pos, front_id, prev_depth, dilated) {
            // Mean and standard deviation of this frame's 3 x 3 neighbourhood.
            var m1 = vec3<f32>(0.0);
            var m2 = vec3<f32>(0.0);
            for (var k = 0; k < 9; k++) {
                let y = rgb_to_ycocg(average(current[index_of(p + vec2<i32>(k % 3 - 1, k / 3 - 1))]));
                m1 += y;
                m2 += y * y;
            }
            m1 /= 9.0;
            let sigma = sqrt(max(m2 / 9.0 - m1 * m1, vec3<f32>(0.0)));
            let h = rgb_to_ycocg(hist);
            let clipped = clip_to_box(h, m1, params.clip_gamma * sigma);
            hist = ycocg_to_rgb(clipped);
        } else {
            n_hist = 0.0;
        }
    }
    let n = n_hist + 1.0;
    let out = hist + (c - hist) / n;
    blended[i] = vec4<f32>(out * n, n);
}
