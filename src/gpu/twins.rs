//! Rust twins of the WGSL structs in `shaders/lib/types.wgsl`: same names,
//! same field names, `#[repr(C)]` and Pod. `tests/shaders.rs` parses the WGSL
//! with naga and checks every size, offset and constant against these.

use bytemuck::{Pod, Zeroable};

pub const SHADING_BLINN_PHONG: u32 = 0;
pub const SHADING_TOON: u32 = 1;
pub const MAX_TOON_BANDS: u32 = 16;
pub const TONE_MAP_CLAMP: u32 = 0;
pub const TONE_MAP_REINHARD: u32 = 1;
/// Workgroup edge of the accumulate kernel (8 x 8 invocations).
pub const ACCUMULATE_WORKGROUP: u32 = 8;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniforms {
    pub clip_from_world: [[f32; 4]; 4],
    pub eye_in_world: [f32; 4],
    pub view_forward: [f32; 4],
    pub ambient: [f32; 4],
    pub background: [f32; 4],
    pub size_px: [u32; 2],
    pub light_count: u32,
    pub sample_index: u32,
    pub jitter_px: [f32; 2],
    pub max_outline_px: f32,
    pub seed: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuLight {
    pub position_or_direction: [f32; 4],
    pub radiance: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuMaterial {
    pub base_color: [f32; 3],
    pub shininess: f32,
    pub specular_color: [f32; 3],
    pub specular_threshold: f32,
    pub outline_color: [f32; 3],
    pub outline_width_px: f32,
    pub rim_color: [f32; 3],
    pub rim_threshold: f32,
    pub model: u32,
    pub band_count: u32,
    pub reflectivity: f32,
    pub roughness: f32,
    pub thresholds: [[f32; 4]; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuInstance {
    pub world_from_object: [[f32; 4]; 4],
    pub normal_from_object: [[f32; 4]; 4],
    pub material: u32,
    pub shape: u32,
    pub mirrored: u32,
    pub _pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ResolveUniforms {
    pub width: u32,
    pub tone_map: u32,
    pub encode_srgb: u32,
    pub exposure: f32,
}

/// A vertex of a triangle mesh as the raster pass reads it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
}

impl Vertex {
    pub const LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<Vertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
    };
}
