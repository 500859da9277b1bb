// Random numbers that depend only on their integer inputs (pixel, sample
// index, seed, bounce), so the same settings give the same image: the WGSL
// twin of hash_u32 / uniform in src/sampling.rs.

fn hash_u32(v: u32) -> u32 {
    var x = v;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

// A uniform number in [0, 1) from three integers.
fn uniform3(a: u32, b: u32, c: u32) -> f32 {
    let h = hash_u32(a ^ hash_u32((b + 0x9e3779b9u) ^ hash_u32(c)));
    return f32(h >> 8u) / 16777216.0;
}
