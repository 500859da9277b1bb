//! Per-image GPU storage: two G-buffers (the raster pass's textures, with
//! its depth target and albedo, and the trace pass's buffers, whose
//! normals, depths and ids are copied into textures where a pass needs
//! those), the float accumulation buffer, and an 8-bit sRGB target for
//! capture.

use crate::gpu::{Gpu, GpuError};

pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
pub const NORMAL_DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
pub const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
/// The raster pass's base colour after images and patterns, read by the
/// trace pass for rasterized hits in hybrid mode.
pub const ALBEDO_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
pub const CAPTURE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// The G-buffer: shaded colour, world normal + view depth, instance id + 1.
/// In raster mode the ids are mostly the colour's alpha and `id` goes
/// unwritten ([`crate::render::raster::ids_in_color`]).
pub struct GBuffer {
    pub color: wgpu::Texture,
    pub normal_depth: wgpu::Texture,
    pub id: wgpu::Texture,
}

/// The traced G-buffer's normal + view depth and ids as textures, copied
/// from [`TracedOutput`] only where a texture is read: by the reproject
/// pass on a moving frame, and by the tests' G-buffer read-backs.
pub struct TracedTextures {
    pub normal_depth: wgpu::Texture,
    pub id: wgpu::Texture,
}

pub use crate::gpu::twins::TRACED_ROW_ALIGN_PX;

/// The trace pass's output, written as plain storage buffers (on lavapipe
/// a storage-texture store costs several times a buffer store;
/// docs/performance-history.md), rows [`TRACED_ROW_ALIGN_PX`]-aligned, each texel
/// in its texture's format. The outline marks and the accumulate pass read
/// them as they are (`shaders/lib/gbuffer.wgsl`); the normal + depth and
/// ids are copied into [`TracedTextures`] only where a texture is read.
pub struct TracedOutput {
    /// Per pixel the colour's four halves (as [`COLOR_FORMAT`] stores them).
    pub color: wgpu::Buffer,
    pub normal_depth: wgpu::Buffer,
    pub id: wgpu::Buffer,
    /// Pixels per row in the buffers.
    pub row_px: u32,
}

impl TracedOutput {
    /// Copies the normal + depth and the id buffers into two textures of
    /// their formats and the targets' size ([`TracedTextures`], or a
    /// reprojection's history).
    pub fn encode_copy(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        normal_depth: &wgpu::Texture,
        id: &wgpu::Texture,
    ) {
        for (buffer, texture) in [(&self.normal_depth, normal_depth), (&self.id, id)] {
            let bytes = texel_bytes(texture.format());
            encoder.copy_buffer_to_texture(
                wgpu::TexelCopyBufferInfo {
                    buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(self.row_px * bytes),
                        rows_per_image: None,
                    },
                },
                texture.as_image_copy(),
                texture.size(),
            );
        }
    }
}

/// Bytes a texel of `format` takes in a buffer copy.
fn texel_bytes(format: wgpu::TextureFormat) -> u32 {
    format.block_copy_size(None).unwrap_or(4)
}

pub struct Targets {
    pub width: u32,
    pub height: u32,
    /// Written by the raster pass.
    pub raster: GBuffer,
    /// Written by the trace pass (hybrid and raytrace modes).
    pub traced_output: TracedOutput,
    pub traced: TracedTextures,
    /// See [`ALBEDO_FORMAT`].
    pub raster_albedo: wgpu::Texture,
    pub depth: wgpu::Texture,
    /// One vec4<f32> per pixel: summed colour in rgb, sample count in w.
    pub accum: wgpu::Buffer,
    pub capture: wgpu::Texture,
}

/// A 2D texture of `w` x `h` texels, one mip level, in `format`.
pub fn texture(
    gpu: &Gpu,
    label: &str,
    w: u32,
    h: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

impl Targets {
    /// Targets for a `width` x `height` image; sizes the adapter cannot hold
    /// are refused with the limit named.
    pub fn new(gpu: &Gpu, width: u32, height: u32) -> Result<Targets, GpuError> {
        let limits = gpu.device.limits();
        let max_dim = limits.max_texture_dimension_2d;
        if width == 0 || height == 0 {
            return Err(GpuError::Unsupported(format!(
                "image size {width}x{height}: width and height must be at least 1"
            )));
        }
        for (what, v) in [("image width", width), ("image height", height)] {
            if v > max_dim {
                return Err(GpuError::Limit {
                    what: what.into(),
                    value: u64::from(v),
                    limit: u64::from(max_dim),
                });
            }
        }
        let accum_bytes = u64::from(width) * u64::from(height) * 16;
        let row_px = width.next_multiple_of(TRACED_ROW_ALIGN_PX);
        // The traced normal + depth buffer, 16 bytes a pixel of its padded
        // rows, is the largest storage buffer bound besides the accumulator.
        let traced_bytes =
            u64::from(row_px) * u64::from(height) * u64::from(texel_bytes(NORMAL_DEPTH_FORMAT));
        let buffer_limit = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        for (what, bytes) in [
            ("accumulation buffer", accum_bytes),
            ("traced normal+depth buffer", traced_bytes),
        ] {
            if bytes > buffer_limit {
                return Err(GpuError::Limit {
                    what: format!("{what} for {width}x{height} (bytes)"),
                    value: bytes,
                    limit: buffer_limit,
                });
            }
        }
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        // The traced textures are filled by copies from TracedOutput, and
        // copied into a reprojection's history.
        let copied = wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::TEXTURE_BINDING;
        let output = |label, format| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: u64::from(row_px) * u64::from(height) * u64::from(texel_bytes(format)),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        gpu.scoped(|| Targets {
            width,
            height,
            raster: GBuffer {
                // Copied out where the ids are its alpha (Renderer::read_ids).
                color: texture(
                    gpu,
                    "raster colour",
                    width,
                    height,
                    COLOR_FORMAT,
                    attach | wgpu::TextureUsages::COPY_SRC,
                ),
                normal_depth: texture(
                    gpu,
                    "raster normal+depth",
                    width,
                    height,
                    NORMAL_DEPTH_FORMAT,
                    attach | wgpu::TextureUsages::COPY_SRC,
                ),
                id: texture(
                    gpu,
                    "raster id",
                    width,
                    height,
                    ID_FORMAT,
                    attach | wgpu::TextureUsages::COPY_SRC,
                ),
            },
            raster_albedo: texture(gpu, "raster albedo", width, height, ALBEDO_FORMAT, attach),
            traced: TracedTextures {
                normal_depth: texture(
                    gpu,
                    "traced normal+depth",
                    width,
                    height,
                    NORMAL_DEPTH_FORMAT,
                    copied | wgpu::TextureUsages::COPY_SRC,
                ),
                id: texture(
                    gpu,
                    "traced id",
                    width,
                    height,
                    ID_FORMAT,
                    copied | wgpu::TextureUsages::COPY_SRC,
                ),
            },
            traced_output: TracedOutput {
                color: output("traced colour output", COLOR_FORMAT),
                normal_depth: output("traced normal+depth output", NORMAL_DEPTH_FORMAT),
                id: output("traced id output", ID_FORMAT),
                row_px,
            },
            depth: texture(
                gpu,
                "depth",
                width,
                height,
                DEPTH_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
            ),
            accum: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("accumulation"),
                size: accum_bytes,
                // COPY_DST: the temporal pass clears it and writes its blend.
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            capture: texture(
                gpu,
                "capture",
                width,
                height,
                CAPTURE_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            ),
        })
    }
}
