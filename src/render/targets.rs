//! Per-image GPU storage: two G-buffers (the raster pass's, with its depth
//! target and albedo, and the trace pass's), the float accumulation
//! buffer, and an 8-bit sRGB target for capture.

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
pub struct GBuffer {
    pub color: wgpu::Texture,
    pub normal_depth: wgpu::Texture,
    pub id: wgpu::Texture,
}

pub struct Targets {
    pub width: u32,
    pub height: u32,
    /// Written by the raster pass.
    pub raster: GBuffer,
    /// Written by the trace pass (hybrid and raytrace modes).
    pub traced: GBuffer,
    /// See [`ALBEDO_FORMAT`].
    pub raster_albedo: wgpu::Texture,
    pub depth: wgpu::Texture,
    /// One vec4<f32> per pixel: summed colour in rgb, sample count in w.
    pub accum: wgpu::Buffer,
    pub capture: wgpu::Texture,
}

fn texture(
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
        let accum_limit = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        if accum_bytes > accum_limit {
            return Err(GpuError::Limit {
                what: format!("accumulation buffer for {width}x{height} (bytes)"),
                value: accum_bytes,
                limit: accum_limit,
            });
        }
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        let storage = wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING;
        gpu.scoped(|| Targets {
            width,
            height,
            raster: GBuffer {
                color: texture(gpu, "raster colour", width, height, COLOR_FORMAT, attach),
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
            traced: GBuffer {
                color: texture(gpu, "traced colour", width, height, COLOR_FORMAT, storage),
                normal_depth: texture(
                    gpu,
                    "traced normal+depth",
                    width,
                    height,
                    NORMAL_DEPTH_FORMAT,
                    storage | wgpu::TextureUsages::COPY_SRC,
                ),
                id: texture(
                    gpu,
                    "traced id",
                    width,
                    height,
                    ID_FORMAT,
                    storage | wgpu::TextureUsages::COPY_SRC,
                ),
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
