// Colour helpers: tone mapping and the sRGB transfer function.

fn tone_map(c: vec3<f32>, mode: u32) -> vec3<f32> {
    if mode == TONE_MAP_REINHARD {
        return c / (vec3<f32>(1.0) + c);
    }
    return clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
}

// Linear to sRGB-encoded, per the sRGB standard (IEC 61966-2-1).
fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let lo = c * 12.92;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}
