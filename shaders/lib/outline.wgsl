// What the outline passes share (shaders/outline_tiles.wgsl and
// shaders/accumulate.wgsl): the bounds that prove a patch of the G-buffer
// the smooth inside of one object, where the outline search can find no
// edge (outline_tiles.wgsl's header gives the argument).

// Per-step bounds for paths of at most 2r steps between neighbouring
// texels, the longest a search of radius r needs: depths within 0.96 end
// to end (an edge is DEPTH_JUMP = 5%), normals within 54 degrees (0.9 of
// accumulate.wgsl's 60-degree CREASE_COS). x: the depth factor a step may
// change by, y: the cosine of the angle a step may turn. The CPU's twin,
// for the tiles it proves smooth itself: accel::screen_tiles::SmoothSteps.
fn smooth_step_bounds(r: i32) -> vec2<f32> {
    let steps = f32(2 * max(r, 1));
    return vec2<f32>(pow(1.0 - 0.8 * DEPTH_JUMP, 1.0 / steps), cos(radians(54.0) / steps));
}

// Whether two neighbouring texels (normal xyz, view depth w), each already
// checked on its own (smooth_texel), are close enough for `bounds`
// of smooth_step_bounds. Written so that a NaN anywhere fails it.
fn smooth_pair(a: vec4<f32>, b: vec4<f32>, bounds: vec2<f32>) -> bool {
    return a.w >= b.w * bounds.x && b.w >= a.w * bounds.x
        && dot(a.xyz, b.xyz) >= bounds.y * sqrt(dot(a.xyz, a.xyz) * dot(b.xyz, b.xyz));
}

// A texel on its own (it also meets the search as p = q): in front of the
// eye, its normal at least 0.949 long.
fn smooth_texel(nd: vec4<f32>) -> bool {
    return nd.w > 0.0 && dot(nd.xyz, nd.xyz) >= 0.9;
}
