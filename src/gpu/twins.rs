//! Rust twins of the WGSL structs in `shaders/lib/types.wgsl` (and
//! `ReprojectUniforms`, declared in `shaders/reproject.wgsl`): same names,
//! same field names, `#[repr(C)]` and Pod. `tests/shaders.rs` parses the WGSL
//! with naga and checks every size, offset and constant against these.
//!
//! What the CPU side builds for the GPU without knowing wgpu (BVH nodes,
//! triangles, shapes, CSG programs, traversal limits) lives in
//! [`crate::accel::layout`] and the CSG and toon limits in [`crate::scene`];
//! this module re-exports them, so every twin is reachable from here. The
//! limits WGSL needs reach it only through the header
//! [`crate::gpu::shader::limits_header`] generates from these constants.

use bytemuck::{Pod, Zeroable};

pub use crate::accel::layout::*;
pub use crate::scene::{CSG_MAX_INTERVALS, CSG_MESH_MAX_CROSSINGS, CSG_STACK, MAX_TOON_BANDS};

pub const SHADING_BLINN_PHONG: u32 = 0;
pub const SHADING_TOON: u32 = 1;
pub const TONE_MAP_CLAMP: u32 = 0;
pub const TONE_MAP_REINHARD: u32 = 1;
/// Edges (pixels) of the accumulate pass's tiles, one workgroup of the
/// accumulate kernels each, and the tiles the outline marks are made for:
/// the first below an outline radius of [`WIDE_OUTLINE_RADIUS`] (where one
/// dispatch can count them), the second otherwise
/// (`render::accumulate::accumulate_tile_px`).
pub const ACCUMULATE_TILES: [u32; 2] = [8, MAX_ACCUMULATE_TILE];
/// The larger edge, which workgroup memory is sized for.
pub const MAX_ACCUMULATE_TILE: u32 = 16;
/// The outline radius (px) from which the larger tiles are used.
pub const WIDE_OUTLINE_RADIUS: u32 = 4;
/// Workgroup size of the outline tile marks (shaders/outline_tiles.wgsl):
/// one invocation per accumulate tile.
pub const OUTLINE_TILES_WORKGROUP: u32 = 64;
/// An outline tile mark: a pixel of the tile may take an outline, so the
/// accumulate pass's `outlined` kernel searches it (0: `main` accumulates
/// it).
pub const OUTLINE_MARK_SEARCH: u32 = 1;
/// An outline tile mark: no outline reaches the tile, and the trace pass
/// has already added its colour to the accumulator (`main` leaves it).
pub const OUTLINE_MARK_TRACED: u32 = 2;
/// The outline dispatch buffer holds `outlined`'s indirect dispatch (words
/// 0-2) and whether it reads the list (word 3), then from this word the
/// accumulate pass's `main`'s indirect dispatch over the tiles the marks
/// left to it (where the trace pass accumulates).
pub const MAIN_DISPATCH_WORD: u32 = 4;
/// Words of the outline dispatch buffer: both indirect dispatches (x, y,
/// z; then a spare word).
pub const OUTLINE_DISPATCH_WORDS: u32 = MAIN_DISPATCH_WORD + 4;

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
    pub world_from_clip: [[f32; 4]; 4],
    pub mode: u32,
    pub max_bounces: u32,
    pub ray_epsilon: f32,
    /// 1 where the trace pass adds the colour of the tiles its tile words
    /// flag [`TILE_TRACE_ACCUMULATES`] to the accumulator itself.
    pub trace_accumulates: u32,
    /// 1 for a trace dispatch that only completes the last sample's
    /// G-buffer (`Renderer::complete_gbuffer`): the tiles that sample left
    /// unstored ([`TILE_GBUFFER_SKIPS`]) store their normal, depth and id,
    /// the others return at once, and nothing is shaded or accumulated.
    pub gbuffer_only: u32,
    pub _pad1: u32,
    pub _pad2: u32,
    pub _pad3: u32,
}

pub const RENDER_MODE_RASTER: u32 = 0;
pub const RENDER_MODE_HYBRID: u32 = 1;
pub const RENDER_MODE_RAYTRACE: u32 = 2;

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
    pub highlight_cos: f32,
    pub outline_color: [f32; 3],
    pub outline_width_px: f32,
    pub rim_color: [f32; 3],
    pub rim_threshold: f32,
    pub model: u32,
    pub band_count: u32,
    pub reflectivity: f32,
    pub roughness: f32,
    pub thresholds: [[f32; 4]; 4],
    pub checker_a: [f32; 3],
    pub checker_size: f32,
    pub checker_b: [f32; 3],
    pub texture_layer: u32,
    pub uv_scale: [f32; 2],
    pub texture_nearest: u32,
    pub _pad: u32,
}

/// [`GpuMaterial::texture_layer`] of a material without an image.
pub const NO_TEXTURE: u32 = u32::MAX;

// A mesh map word (the raster vertex's `map`, the trace pass's
// `triangle_maps`): the array layer in the low bits, the glTF sampler's
// settings above it (all zero: repeat, linear, trilinear), or NO_TEXTURE.
/// Bits of a map word that hold the array layer.
pub const MAP_LAYER_MASK: u32 = 0xff;
/// Shift of the 2-bit wrap mode along u (glTF wrapS).
pub const MAP_WRAP_S_SHIFT: u32 = 8;
/// Shift of the 2-bit wrap mode along v (glTF wrapT).
pub const MAP_WRAP_T_SHIFT: u32 = 10;
/// Wrap mode values (2 bits each).
pub const MAP_WRAP_REPEAT: u32 = 0;
pub const MAP_WRAP_CLAMP: u32 = 1;
pub const MAP_WRAP_MIRROR: u32 = 2;
/// Nearest texel when magnified.
pub const MAP_MAG_NEAREST: u32 = 1 << 12;
/// Nearest texel within a level when minified.
pub const MAP_MIN_NEAREST: u32 = 1 << 13;
/// The nearest mip level rather than a blend of two.
pub const MAP_MIP_NEAREST: u32 = 1 << 14;
/// Level 0 only.
pub const MAP_NO_MIPS: u32 = 1 << 15;

/// The sampler bits of a map word.
pub fn map_sampler_bits(s: &crate::scene::MapSampler) -> u32 {
    use crate::scene::Wrap;
    let wrap = |w: Wrap| match w {
        Wrap::Repeat => MAP_WRAP_REPEAT,
        Wrap::ClampToEdge => MAP_WRAP_CLAMP,
        Wrap::MirroredRepeat => MAP_WRAP_MIRROR,
    };
    let flag = |on: bool, bit: u32| if on { bit } else { 0 };
    wrap(s.wrap_s) << MAP_WRAP_S_SHIFT
        | wrap(s.wrap_t) << MAP_WRAP_T_SHIFT
        | flag(s.mag_nearest, MAP_MAG_NEAREST)
        | flag(s.min_nearest, MAP_MIN_NEAREST)
        | flag(s.mip_nearest, MAP_MIP_NEAREST)
        | flag(s.no_mips, MAP_NO_MIPS)
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuInstance {
    pub world_from_object: [[f32; 4]; 4],
    pub object_from_world: [[f32; 4]; 4],
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
    pub exposure: f32,
    pub _pad: [u32; 2],
}

/// A vertex of a triangle mesh as the raster pass reads it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    /// Texture coordinates (meshes from files; analytic shapes compute
    /// theirs from the object-space position).
    pub uv: [f32; 2],
    /// The mesh's own base-colour map: a texture array layer, or
    /// [`NO_TEXTURE`].
    pub map: u32,
}

impl Vertex {
    pub const LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<Vertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Uint32],
    };
}

/// Loop iterations one pixel of the trace kernel may spend on traversal,
/// all its rays together: well under lavapipe's silent cut at ~65,535.
pub const MAX_INVOCATION_STEPS: u32 = 48000;
/// View depth of the G-buffer where no surface is hit (the largest finite
/// f16, so it survives every target format).
pub const FAR_DEPTH: f32 = 65504.0;
/// Widest outline the accumulate pass draws, in pixels: wider material
/// outlines are drawn this wide (it sizes the workgroup's tile halo).
pub const MAX_OUTLINE_RADIUS: u32 = 8;
/// `LIGHT_COUNT` of lib/shading.wgsl when the light count is not fixed per
/// pipeline: loops run to `frame.light_count`.
pub const LIGHTS_DYNAMIC: u32 = u32::MAX;
/// Workgroup edge of the trace kernel (8 x 8 invocations).
pub const TRACE_WORKGROUP: u32 = 8;

/// Rows of the trace kernel's output buffers start every this many pixels
/// (`render::targets::TracedOutput`): a copy into a texture needs rows
/// 256-byte aligned, and 64 pixels of the narrowest texel (4 bytes) are 256.
pub const TRACED_ROW_ALIGN_PX: u32 = 64;
const _: () =
    assert!(TRACED_ROW_ALIGN_PX.is_power_of_two() && (TRACED_ROW_ALIGN_PX * 4).is_multiple_of(256));
// The trace kernel lays its invocations out in 4 x 2 blocks (trace.wgsl).
const _: () = assert!(TRACE_WORKGROUP.is_multiple_of(4));
/// Workgroup size of the ray-batch kernel used by tests.
pub const RAY_BATCH_WORKGROUP: u32 = 64;

/// A ray for the ray-batch kernel (tests and benchmarks): `origin.w` is
/// t_min and `dir.w` is t_max.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuRay {
    pub origin: [f32; 4],
    pub dir: [f32; 4],
}

/// The closest hit of a [`GpuRay`]: `instance` is u32::MAX on a miss;
/// `steps` counts loop iterations, `overflow` is 1 when the query gave up.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GpuHit {
    pub normal: [f32; 3],
    pub t: f32,
    pub instance: u32,
    pub steps: u32,
    pub overflow: u32,
    pub _pad: u32,
}

/// Workgroup edge of the reproject kernel (8 x 8 invocations).
pub const REPROJECT_WORKGROUP: u32 = 8;
/// [`ReprojectUniforms::rejection`]: blend the reprojected history blindly
/// (a plain exponential blend: ghosts where the view uncovers something).
pub const TEMPORAL_REJECT_NONE: u32 = 0;
/// [`ReprojectUniforms::rejection`]: reject the history on disocclusion
/// (object id, view depth) and clip it to the current neighbourhood.
pub const TEMPORAL_REJECT_CLIP: u32 = 1;

/// Uniforms of the reproject pass (`shaders/reproject.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ReprojectUniforms {
    /// This frame's camera without jitter or lens offset.
    pub cur_clip_from_world: [[f32; 4]; 4],
    /// The previous frame's camera without jitter or lens offset.
    pub prev_clip_from_world: [[f32; 4]; 4],
    pub prev_eye: [f32; 4],
    /// Unit forward of the previous camera.
    pub prev_forward: [f32; 4],
    /// The most samples a history may count while the view moves.
    pub max_history: f32,
    /// Half-width of the clipping box in standard deviations.
    pub clip_gamma: f32,
    /// Relative view-depth difference beyond which the history is rejected.
    pub depth_tolerance: f32,
    /// `TEMPORAL_REJECT_*`.
    pub rejection: u32,
}
