// Colour helpers: tone mapping, the sRGB transfer function, half floats.

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

// The half-precision bits of x, rounded toward zero (overflow to the
// largest half). That is what lavapipe's store into an rgba16float texture
// writes: the trace pass packs its colour with it (into a buffer that is
// copied into such a texture), and gets the bits a texture store would.
fn half_bits_toward_zero(x: f32) -> u32 {
    let b = bitcast<u32>(x);
    let sign = (b >> 16u) & 0x8000u;
    let a = b & 0x7fffffffu;
    if a > 0x7f800000u {
        return sign | 0x7e00u; // NaN
    }
    if a == 0x7f800000u {
        return sign | 0x7c00u; // infinity
    }
    if a >= 0x47800000u {
        return sign | 0x7bffu; // past the largest half: the largest half
    }
    if a >= 0x38800000u {
        return sign | ((a - 0x38000000u) >> 13u); // normal: rebias, drop 13 bits
    }
    if a < 0x33000000u {
        return sign; // under 2^-25: zero, as every value under 2^-24 is
    }
    // Subnormal: the 24-bit significand shifted to units of 2^-24.
    let significand = (a & 0x7fffffu) | 0x800000u;
    return sign | (significand >> (126u - (a >> 23u)));
}

// A linear colour as the traced G-buffer holds it: four halves (alpha 1),
// each rounded toward zero (half_bits_toward_zero).
fn pack_color_halves(c: vec3<f32>) -> vec2<u32> {
    return vec2<u32>(
        half_bits_toward_zero(c.r) | half_bits_toward_zero(c.g) << 16u,
        half_bits_toward_zero(c.b) | half_bits_toward_zero(1.0) << 16u,
    );
}

// The colour pack_color_halves packed (the halves widen exactly).
fn unpack_color_halves(h: vec2<u32>) -> vec3<f32> {
    return vec3<f32>(unpack2x16float(h.x), unpack2x16float(h.y).x);
}
