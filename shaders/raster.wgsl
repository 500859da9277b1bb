// Raster pass: one instanced draw per (base shape, cull mode) group (every
// instance in raster mode, the meshes in hybrid mode), shaded in the
// fragment shader into the G-buffer (colour, normal + depth, id; and the
// albedo in the textured variant). In hybrid mode the trace pass shades
// every pixel, rasterized ones too, from the normal, depth, id and albedo
// written here: its pipelines leave the colour target unwritten (so the
// driver drops the shading as dead code), and untextured scenes run the
// geometry entry points (vs_geometry, fs_geometry), which do not pass the
// material's shading fields either (docs/performance-history.md).

#include "lib/types.wgsl"
#include "lib/scene_bindings.wgsl"
#include "lib/shading.wgsl"
#include "lib/intersect.wgsl"
#include "lib/texture.wgsl"

// Group 0: the scene (lib/scene_bindings.wgsl). Group 1: this pass's own.
@group(1) @binding(0) var<uniform> frame: FrameUniforms;

// One output for both vertex entry points: vs_main leaves the textured
// inputs (locations 11 to 13) zero, and fs_main does not read them, so the
// CPU driver does not interpolate them there.
struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_pos: vec3<f32>,
    @location(1) world_normal: vec3<f32>,
    // The instance, its material, 1 when its transform mirrors, and the
    // mesh's own base-colour map word (layer and sampler bits), or
    // NO_TEXTURE (vs_textured only).
    @location(2) @interpolate(flat) ids: vec4<u32>,
    // The material's shading fields, read once per vertex and passed flat:
    // a fragment reading them from the storage buffer costs the CPU driver
    // a gather per field per fragment (it cannot tell that all fragments of
    // a triangle share the material).
    @location(3) @interpolate(flat) base_shininess: vec4<f32>,
    @location(4) @interpolate(flat) specular: vec4<f32>,
    @location(5) @interpolate(flat) rim: vec4<f32>,
    @location(6) @interpolate(flat) model_bands: vec2<u32>,
    @location(7) @interpolate(flat) thresholds0: vec4<f32>,
    @location(8) @interpolate(flat) thresholds1: vec4<f32>,
    @location(9) @interpolate(flat) thresholds2: vec4<f32>,
    @location(10) @interpolate(flat) thresholds3: vec4<f32>,
    // What textured scenes' fragments also need (vs_textured / fs_textured).
    @location(11) object_pos: vec3<f32>,
    @location(12) object_normal: vec3<f32>,
    @location(13) uv: vec2<f32>,
}

// VsOut without the material's shading fields: what untextured hybrid
// mode's fragments read (vs_geometry, fs_geometry).
struct GeometryOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_pos: vec3<f32>,
    @location(1) world_normal: vec3<f32>,
    @location(2) @interpolate(flat) ids: vec4<u32>,
}

// A vertex of `instance`: its clip and world position, world normal and
// ids.
fn geometry_vertex(position: vec3<f32>, normal: vec3<f32>, instance: u32) -> GeometryOut {
    let p = load_instance(instance).world_from_object * vec4<f32>(position, 1.0);
    var out: GeometryOut;
    out.clip = frame.clip_from_world * p;
    out.world_pos = p.xyz;
    out.world_normal = (load_instance(instance).normal_from_object * vec4<f32>(normal, 0.0)).xyz;
    out.ids = vec4<u32>(instance, load_instance(instance).material, load_instance(instance).mirrored, NO_TEXTURE);
    return out;
}

// A vertex of `instance` with its material's shading fields (the textured
// inputs left zero).
fn shade_vertex(position: vec3<f32>, normal: vec3<f32>, instance: u32) -> VsOut {
    // Field by field: copying the whole struct costs on CPU drivers.
    let g = geometry_vertex(position, normal, instance);
    var out: VsOut;
    out.clip = g.clip;
    out.world_pos = g.world_pos;
    out.world_normal = g.world_normal;
    out.ids = g.ids;
    let material = g.ids.y;
    out.base_shininess = vec4<f32>(load_material(material).base_color, load_material(material).shininess);
    out.specular = vec4<f32>(load_material(material).specular_color, load_material(material).highlight_cos);
    out.rim = vec4<f32>(load_material(material).rim_color, load_material(material).rim_threshold);
    out.model_bands = vec2<u32>(load_material(material).model, load_material(material).band_count);
    // Only the thresholds the scene's materials fill (lib/shading.wgsl).
    out.thresholds0 = load_material(material).thresholds[0];
    if TOON_THRESHOLD_VECS > 1u {
        out.thresholds1 = load_material(material).thresholds[1];
    }
    if TOON_THRESHOLD_VECS > 2u {
        out.thresholds2 = load_material(material).thresholds[2];
    }
    if TOON_THRESHOLD_VECS > 3u {
        out.thresholds3 = load_material(material).thresholds[3];
    }
    return out;
}

@vertex
fn vs_main(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @builtin(instance_index) instance: u32,
) -> VsOut {
    return shade_vertex(position, normal, instance);
}

@vertex
fn vs_textured(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) map: u32,
    @builtin(instance_index) instance: u32,
) -> VsOut {
    var out = shade_vertex(position, normal, instance);
    out.ids.w = map;
    out.object_pos = position;
    out.object_normal = normal;
    out.uv = uv;
    return out;
}

@vertex
fn vs_geometry(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @builtin(instance_index) instance: u32,
) -> GeometryOut {
    return geometry_vertex(position, normal, instance);
}

// The material's shading fields, from the flat inputs; the others stay
// zero (fs_textured loads the texture fields it needs).
fn flat_material(in: VsOut) -> GpuMaterial {
    var m: GpuMaterial;
    m.base_color = in.base_shininess.xyz;
    m.shininess = in.base_shininess.w;
    m.specular_color = in.specular.xyz;
    m.highlight_cos = in.specular.w;
    m.rim_color = in.rim.xyz;
    m.rim_threshold = in.rim.w;
    m.model = in.model_bands.x;
    m.band_count = in.model_bands.y;
    m.thresholds = array<vec4<f32>, 4>(in.thresholds0, in.thresholds1, in.thresholds2, in.thresholds3);
    return m;
}

struct GBuffer {
    // The shaded colour, and in alpha the id below as a float: a half holds
    // every integer up to 2048 exactly, so raster mode drops the id target
    // (one colour target fewer for the CPU driver's fragment path) and its
    // readers take the id from here where the scene has at most
    // MAX_IDS_IN_COLOR instances (src/render/raster.rs, ids_in_color).
    @location(0) color: vec4<f32>,
    // World-space unit normal and view depth.
    @location(1) normal_depth: vec4<f32>,
    // Instance index + 1; 0 is background.
    @location(2) id: u32,
}

struct GBufferTextured {
    @location(0) color: vec4<f32>,
    @location(1) normal_depth: vec4<f32>,
    @location(2) id: u32,
    // The base colour after images and patterns (the trace pass shades
    // rasterized hits with it in hybrid mode).
    @location(3) albedo: vec4<f32>,
}

// Untextured hybrid mode's outputs: no colour (its target's write mask is
// empty).
struct Geometry {
    @location(1) normal_depth: vec4<f32>,
    @location(2) id: u32,
}

// The fragment's unit normal, facing the side it is seen from, and its view
// depth. Two-sided surfaces (planes) shade their back with the flipped
// normal; a mirroring transform flips the winding, so flip the test with it.
fn normal_depth(world_pos: vec3<f32>, world_normal: vec3<f32>, mirrored: u32, front_facing: bool) -> vec4<f32> {
    var n = normalize(world_normal);
    if front_facing == (mirrored == 1u) {
        n = -n;
    }
    return vec4<f32>(n, dot(world_pos - frame.eye_in_world.xyz, frame.view_forward.xyz));
}

// Shades one fragment with material m (its base colour already resolved).
fn shade_fragment(m: GpuMaterial, world_pos: vec3<f32>, world_normal: vec3<f32>, instance: u32, mirrored: u32, front_facing: bool) -> GBuffer {
    let nd = normal_depth(world_pos, world_normal, mirrored, front_facing);
    let n = nd.xyz;
    let v = normalize(frame.eye_in_world.xyz - world_pos);
    var c = shade_ambient(m, n, v, frame.ambient.rgb);
    for (var i = 0u; i < light_loop_count(frame.light_count); i++) {
        let ls = sample_light(i, lights[i], world_pos);
        c += shade_light(m, n, v, ls.to_light, ls.radiance);
    }
    var out: GBuffer;
    out.color = vec4<f32>(c, f32(instance + 1u));
    out.normal_depth = nd;
    out.id = instance + 1u;
    return out;
}

// m with the fields raster_albedo reads from the material table, one load
// each (not the whole struct).
fn with_albedo_fields(m: GpuMaterial, material: u32) -> GpuMaterial {
    var out = m;
    out.checker_a = load_material(material).checker_a;
    out.checker_size = load_material(material).checker_size;
    out.checker_b = load_material(material).checker_b;
    out.texture_layer = load_material(material).texture_layer;
    out.uv_scale = load_material(material).uv_scale;
    out.texture_nearest = load_material(material).texture_nearest;
    return out;
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front_facing: bool) -> GBuffer {
    return shade_fragment(flat_material(in), in.world_pos, in.world_normal, in.ids.x, in.ids.z, front_facing);
}

@fragment
fn fs_textured(in: VsOut, @builtin(front_facing) front_facing: bool) -> GBufferTextured {
    var m = with_albedo_fields(flat_material(in), in.ids.y);
    m.base_color = raster_albedo(in.object_pos, in.object_normal, in.uv, in.ids, m);
    let g = shade_fragment(m, in.world_pos, in.world_normal, in.ids.x, in.ids.z, front_facing);
    return GBufferTextured(g.color, g.normal_depth, g.id, vec4<f32>(m.base_color, 1.0));
}

@fragment
fn fs_geometry(in: GeometryOut, @builtin(front_facing) front_facing: bool) -> Geometry {
    return Geometry(normal_depth(in.world_pos, in.world_normal, in.ids.z, front_facing), in.ids.x + 1u);
}

// The base colour at a fragment: the checker at its object-space point, or
// the material's image, else the mesh's own, at its texture coordinates
// (analytic shapes compute theirs from the object-space point), trilinear
// at the mip level of the footprint between neighbouring pixels. Only
// interpolated inputs are differentiated, before any branch: Mesa 22.3's
// lavapipe does not run helper invocations through a branch, so the
// derivative of a value assigned inside one is garbage on the edges of
// every triangle. An analytic shape's step in uv is the difference of its
// mapping at the point and at the point one pixel over (the same finite
// difference as the trace pass's), taken the short way round a longitude
// seam.
// `ids` as in VsOut.
fn raster_albedo(object_pos: vec3<f32>, object_normal: vec3<f32>, mesh_uv: vec2<f32>, ids: vec4<u32>, m: GpuMaterial) -> vec3<f32> {
    let dp_dx = dpdxFine(object_pos);
    let dp_dy = dpdyFine(object_pos);
    var dx = dpdxFine(mesh_uv);
    var dy = dpdyFine(mesh_uv);
    let shape = load_shape(load_instance(ids.x).shape);
    var uv = mesh_uv;
    if shape.kind != SHAPE_MESH {
        let p = object_pos;
        let n = object_normal;
        let periodic = periodic_u(shape.kind, n);
        uv = analytic_uv(shape.kind, shape.params, p, n);
        dx = wrap_du(analytic_uv(shape.kind, shape.params, p + dp_dx, n) - uv, periodic);
        dy = wrap_du(analytic_uv(shape.kind, shape.params, p + dp_dy, n) - uv, periodic);
    }
    // The mip level by the same formula as the trace pass's, so hybrid
    // agrees with raytrace.
    let lod = footprint_lod(dx * m.uv_scale, dy * m.uv_scale);
    if m.checker_size > 0.0 {
        return checker(m, object_pos);
    }
    if m.texture_layer != NO_TEXTURE {
        return sample_map_level(m.texture_layer, m.texture_nearest != 0u, uv * m.uv_scale, lod);
    }
    if ids.w != NO_TEXTURE {
        return sample_map(ids.w, uv * m.uv_scale, lod);
    }
    return m.base_color;
}
