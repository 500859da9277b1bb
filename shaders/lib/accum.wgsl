// Adding a sample to the float accumulator, which the accumulate pass
// does for every pixel and the trace pass for the pixels of the tiles no
// outline can reach (shaders/trace.wgsl): both the same way, so that
// either gives the same sums bit for bit.
//
// Includes: after `frame` (FrameUniforms) and
// `accum: array<vec4<f32>>` (read_write storage).

// Adds colour c to the sum of pixel p (or starts it on the first sample);
// w counts the samples, so the resolve divides by it.
fn add_sample(p: vec2<u32>, c: vec3<f32>) {
    let i = p.y * frame.size_px.x + p.x;
    if frame.sample_index == 0u {
        accum[i] = vec4<f32>(c, 1.0);
    } else {
        accum[i] += vec4<f32>(c, 1.0);
    }
}
