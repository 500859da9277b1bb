// Base colour from images and patterns, shared by the raster and trace
// passes. It reads the scene's `base_color_maps` (texture_2d_array<f32>,
// sRGB-decoding), `map_linear` and `map_nearest` (samplers), declared in
// lib/scene_bindings.wgsl, and needs lib/intersect.wgsl's SHAPE_* constants.

// False in pipelines for scenes whose materials have no image or pattern:
// the texture code is compiled out.
override TEXTURES_ENABLED: bool = true;

const TAU: f32 = 6.283185307;
const PI_F: f32 = 3.141592654;

// Longitude in [0, 1]: atan2(z, x) / 2 pi + 1/2, so 1/2 at +x, growing
// towards +z, the seam (0 and 1) at -x.
fn longitude(p: vec3<f32>) -> f32 {
    return atan2(p.z, p.x) / TAU + 0.5;
}

// Texture coordinates of an analytic shape at object-space point p with
// object-space normal n (which picks a box face, a cap or the side).
// (0, 0) is the image's top-left corner. Quad: x from -half.x to +half.x
// is u 0..1, z likewise v; disks and caps: their bounding square the same
// way; sphere: u = longitude, v = 0 at the north pole (+y) to 1 at the
// south; cylinder and cone sides: u = longitude, v = 0 at the top; box
// faces: the whole image on each face, upright on the four sides.
fn analytic_uv(kind: u32, params: vec4<f32>, p: vec3<f32>, n: vec3<f32>) -> vec2<f32> {
    switch kind {
        case SHAPE_QUAD: {
            return (p.xz + params.xy) / (2.0 * params.xy);
        }
        case SHAPE_DISK: {
            return (p.xz + params.xx) / (2.0 * params.x);
        }
        case SHAPE_BOX: {
            let h = params.xyz;
            let a = abs(n);
            if a.y >= a.x && a.y >= a.z {
                let v = (p.z + h.z) / (2.0 * h.z);
                return vec2<f32>((p.x + h.x) / (2.0 * h.x), select(1.0 - v, v, n.y > 0.0));
            }
            let v = (h.y - p.y) / (2.0 * h.y);
            if a.x >= a.z {
                let u = (p.z + h.z) / (2.0 * h.z);
                return vec2<f32>(select(u, 1.0 - u, n.x > 0.0), v);
            }
            let u = (p.x + h.x) / (2.0 * h.x);
            return vec2<f32>(select(1.0 - u, u, n.z > 0.0), v);
        }
        case SHAPE_CYLINDER, SHAPE_CONE: {
            let r = params.x;
            if abs(n.y) > 0.999 {
                let v = (p.z + r) / (2.0 * r);
                return vec2<f32>((p.x + r) / (2.0 * r), select(1.0 - v, v, n.y > 0.0));
            }
            let top = select(params.y, 0.5 * params.y, kind == SHAPE_CYLINDER);
            return vec2<f32>(longitude(p), (top - p.y) / params.y);
        }
        default: {
            // Sphere, and CSG solids: longitude and latitude about the origin.
            let d = normalize(p);
            return vec2<f32>(longitude(d), acos(clamp(d.y, -1.0, 1.0)) / PI_F);
        }
    }
}

// Whether u wraps around (longitude): derivatives and differences across
// the seam are taken the short way round.
fn periodic_u(kind: u32, n: vec3<f32>) -> bool {
    return kind == SHAPE_SPHERE || ((kind == SHAPE_CYLINDER || kind == SHAPE_CONE) && abs(n.y) <= 0.999) || kind > SHAPE_MESH;
}

// The checker: colour a where the sum of the cell indices is even.
fn checker(m: GpuMaterial, p: vec3<f32>) -> vec3<f32> {
    let cell = floor(p / m.checker_size + 0.5);
    let parity = (i32(cell.x) + i32(cell.y) + i32(cell.z)) & 1;
    return select(m.checker_a, m.checker_b, parity != 0);
}

// Whether the material takes its base colour from an image or a pattern.
fn has_base_color_map(m: GpuMaterial) -> bool {
    return m.checker_size > 0.0 || m.texture_layer != NO_TEXTURE;
}

// Layer `layer` at uv at mip level `lod` (trace: from the ray cone).
fn sample_map_level(layer: u32, nearest: bool, uv: vec2<f32>, lod: f32) -> vec3<f32> {
    if nearest {
        return textureSampleLevel(base_color_maps, map_nearest, uv, layer, lod).rgb;
    }
    return textureSampleLevel(base_color_maps, map_linear, uv, layer, lod).rgb;
}

// One texture coordinate wrapped by a glTF wrap mode, kept at least h
// (half a texel of the level sampled) inside the edges for clamp and
// mirror, so that the samplers' own repeat addressing never blends in the
// opposite edge: clamp = the edge texel beyond [0, 1], mirror = reflected
// every other period. Repeat is left to the sampler (it repeats).
fn wrap_coord(x: f32, mode: u32, h: f32) -> f32 {
    if mode == MAP_WRAP_CLAMP {
        return clamp(x, h, 1.0 - h);
    }
    if mode == MAP_WRAP_MIRROR {
        let t = x - 2.0 * floor(0.5 * x);
        return clamp(1.0 - abs(t - 1.0), h, 1.0 - h);
    }
    return x;
}

// Mip level `level` (a whole number) of layer `layer` at uv wrapped by
// the map word's modes, nearest or bilinear within the level.
fn map_tap(word: u32, uv: vec2<f32>, level: f32, nearest: bool) -> vec3<f32> {
    let layer = word & MAP_LAYER_MASK;
    let edge = max(textureDimensions(base_color_maps).x >> u32(level), 1u);
    let h = 0.5 / f32(edge);
    let st = vec2<f32>(
        wrap_coord(uv.x, (word >> MAP_WRAP_S_SHIFT) & 3u, h),
        wrap_coord(uv.y, (word >> MAP_WRAP_T_SHIFT) & 3u, h),
    );
    if nearest {
        return textureSampleLevel(base_color_maps, map_nearest, st, layer, level).rgb;
    }
    return textureSampleLevel(base_color_maps, map_linear, st, layer, level).rgb;
}

// A map word (layer and glTF sampler bits) at uv at mip level `lod`, as a
// glTF viewer samples it: lod <= 0 is magnification (the mag filter at
// level 0); otherwise the min filter at level 0 (no mips), at the nearest
// level, or blended between the two levels around lod. The default word
// (repeat, trilinear) is one hardware trilinear sample, as before.
fn sample_map(word: u32, uv: vec2<f32>, lod: f32) -> vec3<f32> {
    if word <= MAP_LAYER_MASK {
        return sample_map_level(word, false, uv, lod);
    }
    let mag = lod <= 0.0;
    let nearest = select((word & MAP_MIN_NEAREST) != 0u, (word & MAP_MAG_NEAREST) != 0u, mag);
    if mag || (word & MAP_NO_MIPS) != 0u {
        return map_tap(word, uv, 0.0, nearest);
    }
    let top = f32(textureNumLevels(base_color_maps) - 1u);
    let l = min(lod, top);
    if (word & MAP_MIP_NEAREST) != 0u {
        return map_tap(word, uv, floor(l + 0.5), nearest);
    }
    let l0 = floor(l);
    let a = map_tap(word, uv, l0, nearest);
    if l <= l0 {
        return a;
    }
    return mix(a, map_tap(word, uv, l0 + 1.0, nearest), l - l0);
}

// The mip level whose texels match a footprint whose two axes span the
// texture-coordinate steps duv1 and duv2 (the larger one decides, as
// hardware trilinear filtering does).
fn footprint_lod(duv1: vec2<f32>, duv2: vec2<f32>) -> f32 {
    let size = f32(textureDimensions(base_color_maps).x);
    let g = max(length(duv1), length(duv2)) * size;
    return log2(max(g, 1e-6));
}

// A step in u taken the short way round a periodic seam.
fn wrap_du(d: vec2<f32>, periodic: bool) -> vec2<f32> {
    return select(d, vec2<f32>(d.x - round(d.x), d.y), periodic);
}
