// Raster pass: every instance of a base shape in one instanced draw, shaded
// in the fragment shader into the G-buffer (colour, normal + depth, id).

#include "lib/types.wgsl"
#include "lib/shading.wgsl"

@group(0) @binding(0) var<uniform> frame: FrameUniforms;
@group(0) @binding(1) var<storage, read> instances: array<GpuInstance>;
@group(0) @binding(2) var<storage, read> materials: array<GpuMaterial>;
@group(0) @binding(3) var<storage, read> lights: array<GpuLight>;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_pos: vec3<f32>,
    @location(1) world_normal: vec3<f32>,
    @location(2) @interpolate(flat) instance: u32,
    @location(3) @interpolate(flat) material: u32,
    @location(4) @interpolate(flat) mirrored: u32,
    // The material's shading fields, read once per vertex and passed flat:
    // a fragment reading them from the storage buffer costs the CPU driver
    // a gather per field per fragment (it cannot tell that all fragments of
    // a triangle share the material).
    @location(5) @interpolate(flat) base_shininess: vec4<f32>,
    @location(6) @interpolate(flat) specular: vec4<f32>,
    @location(7) @interpolate(flat) rim: vec4<f32>,
    @location(8) @interpolate(flat) model_bands: vec2<u32>,
    @location(9) @interpolate(flat) thresholds0: vec4<f32>,
    @location(10) @interpolate(flat) thresholds1: vec4<f32>,
    @location(11) @interpolate(flat) thresholds2: vec4<f32>,
    @location(12) @interpolate(flat) thresholds3: vec4<f32>,
}

@vertex
fn vs_main(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @builtin(instance_index) instance: u32,
) -> VsOut {
    // Field by field: copying the whole struct costs on CPU drivers.
    let p = instances[instance].world_from_object * vec4<f32>(position, 1.0);
    var out: VsOut;
    out.clip = frame.clip_from_world * p;
    out.world_pos = p.xyz;
    out.world_normal = (instances[instance].normal_from_object * vec4<f32>(normal, 0.0)).xyz;
    out.instance = instance;
    let material = instances[instance].material;
    out.material = material;
    out.mirrored = instances[instance].mirrored;
    out.base_shininess = vec4<f32>(materials[material].base_color, materials[material].shininess);
    out.specular = vec4<f32>(materials[material].specular_color, materials[material].specular_threshold);
    out.rim = vec4<f32>(materials[material].rim_color, materials[material].rim_threshold);
    out.model_bands = vec2<u32>(materials[material].model, materials[material].band_count);
    out.thresholds0 = materials[material].thresholds[0];
    out.thresholds1 = materials[material].thresholds[1];
    out.thresholds2 = materials[material].thresholds[2];
    out.thresholds3 = materials[material].thresholds[3];
    return out;
}

struct GBuffer {
    @location(0) color: vec4<f32>,
    // World-space unit normal and view depth.
    @location(1) normal_depth: vec4<f32>,
    // Instance index + 1; 0 is background.
    @location(2) id: u32,
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front_facing: bool) -> GBuffer {
    // The fields shading reads, from the flat inputs; the rest are unused.
    let m = GpuMaterial(
        in.base_shininess.xyz, in.base_shininess.w,
        in.specular.xyz, in.specular.w,
        vec3<f32>(0.0), 0.0,
        in.rim.xyz, in.rim.w,
        in.model_bands.x, in.model_bands.y, 0.0, 0.0,
        array<vec4<f32>, 4>(in.thresholds0, in.thresholds1, in.thresholds2, in.thresholds3),
    );
    var n = normalize(in.world_normal);
    // Two-sided surfaces (planes) shade their back with the flipped normal;
    // a mirroring transform flips the winding, so flip the test with it.
    if front_facing == (in.mirrored == 1u) {
        n = -n;
    }
    let eye = frame.eye_in_world.xyz;
    let v = normalize(eye - in.world_pos);
    var c = shade_ambient(m, n, v, frame.ambient.rgb);
    for (var i = 0u; i < frame.light_count; i++) {
        let ls = sample_light(lights[i], in.world_pos);
        c += shade_light(m, n, v, ls.to_light, ls.radiance);
    }
    var out: GBuffer;
    out.color = vec4<f32>(c, 1.0);
    out.normal_depth = vec4<f32>(n, dot(in.world_pos - eye, frame.view_forward.xyz));
    out.id = in.instance + 1u;
    return out;
}
