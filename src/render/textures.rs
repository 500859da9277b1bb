//! Base-colour images on the GPU: one 2D texture array (the CPU driver has
//! no binding arrays), every image resampled to one square layer size with
//! a full mip chain built on the CPU in linear light, plus a trilinear
//! and a nearest sampler.

use std::sync::Arc;

use crate::gpu::twins::{map_sampler_bits, MAP_LAYER_MASK, NO_TEXTURE};

// Every layer index fits in a map word's layer bits.
const _: () = assert!(MAX_TEXTURES as u32 <= MAP_LAYER_MASK + 1);
use crate::gpu::{Gpu, GpuError};
use crate::scene::{srgb_to_linear, Scene, Shape, Texture, MAX_TEXTURES, MAX_TEXTURE_SIZE};

/// Format of the array: sampling decodes sRGB to linear.
pub const MAP_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

pub struct SceneTextures {
    pub view: wgpu::TextureView,
    pub linear: wgpu::Sampler,
    pub nearest: wgpu::Sampler,
    /// `layers[i]` is the image in array layer i.
    pub layers: Vec<Arc<Texture>>,
    /// Edge of every layer in texels (1 when the scene has no image).
    pub layer_size: u32,
}

/// Every distinct image the scene uses, in first-use order: the
/// materials', then the meshes' own (in shape order).
pub fn scene_images(scene: &Scene) -> Vec<Arc<Texture>> {
    let mut out: Vec<Arc<Texture>> = Vec::new();
    let mut add = |t: &Arc<Texture>| {
        if !out.iter().any(|o| Arc::ptr_eq(o, t)) {
            out.push(t.clone());
        }
    };
    for m in &scene.materials {
        if let Some(t) = &m.base_color_texture {
            add(&t.texture);
        }
    }
    for shape in &scene.shapes {
        if let Shape::Mesh(mesh) = shape {
            mesh.textures.iter().for_each(&mut add);
        }
    }
    out
}

/// Whether the scene needs texture code: a material some surface shows
/// with an image or a pattern, or a mesh an instance shows with its own
/// maps.
pub fn scene_uses_textures(scene: &Scene) -> bool {
    scene
        .used_materials()
        .any(|m| m.base_color_texture.is_some() || m.base_color_pattern.is_some())
        || scene
            .used_shapes()
            .any(|(_, s)| matches!(s, Shape::Mesh(m) if !m.textures.is_empty()))
}

impl SceneTextures {
    /// Uploads the scene's images (a 1x1 white layer when there are none).
    pub fn upload(gpu: &Gpu, scene: &Scene) -> Result<SceneTextures, GpuError> {
        let layers = scene_images(scene);
        if layers.len() > MAX_TEXTURES {
            return Err(GpuError::Limit {
                what: "base-colour textures".into(),
                value: layers.len() as u64,
                limit: MAX_TEXTURES as u64,
            });
        }
        let limits = gpu.device.limits();
        let size = layers
            .iter()
            .map(|t| t.width.max(t.height))
            .max()
            .unwrap_or(1)
            .clamp(1, MAX_TEXTURE_SIZE.min(limits.max_texture_dimension_2d));
        let layer_count = (layers.len() as u32).max(1);
        if layer_count > limits.max_texture_array_layers {
            return Err(GpuError::Limit {
                what: "texture array layers".into(),
                value: u64::from(layer_count),
                limit: u64::from(limits.max_texture_array_layers),
            });
        }
        let mip_count = 32 - size.leading_zeros();
        let texture = gpu.scoped(|| {
            gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("base-colour maps"),
                size: wgpu::Extent3d {
                    width: size,
                    height: size,
                    depth_or_array_layers: layer_count,
                },
                mip_level_count: mip_count,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: MAP_FORMAT,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            })
        })?;
        let white = Texture {
            source: "white".into(),
            path: Default::default(),
            width: 1,
            height: 1,
            rgba8: vec![255; 4],
        };
        let images: Vec<&Texture> = if layers.is_empty() {
            vec![&white]
        } else {
            layers.iter().map(|t| t.as_ref()).collect()
        };
        for (layer, image) in images.iter().enumerate() {
            for (level, (edge, texels)) in mip_chain(image, size).into_iter().enumerate() {
                gpu.queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &texture,
                        mip_level: level as u32,
                        origin: wgpu::Origin3d {
                            x: 0,
                            y: 0,
                            z: layer as u32,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    &texels,
                    wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(edge * 4),
                        rows_per_image: Some(edge),
                    },
                    wgpu::Extent3d {
                        width: edge,
                        height: edge,
                        depth_or_array_layers: 1,
                    },
                );
            }
        }
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("base-colour maps view"),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let sampler = |label, filter: wgpu::FilterMode, mip, anisotropy| {
            gpu.device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some(label),
                address_mode_u: wgpu::AddressMode::Repeat,
                address_mode_v: wgpu::AddressMode::Repeat,
                address_mode_w: wgpu::AddressMode::Repeat,
                mag_filter: filter,
                min_filter: filter,
                mipmap_filter: mip,
                anisotropy_clamp: anisotropy,
                ..Default::default()
            })
        };
        Ok(SceneTextures {
            view,
            linear: sampler(
                "base-colour sampler (trilinear)",
                wgpu::FilterMode::Linear,
                wgpu::MipmapFilterMode::Linear,
                // Isotropic: the trace pass picks one mip level per hit, and
                // hybrid mode must agree with raytrace mode.
                1,
            ),
            nearest: sampler(
                "base-colour sampler (nearest)",
                wgpu::FilterMode::Nearest,
                wgpu::MipmapFilterMode::Nearest,
                1,
            ),
            layers,
            layer_size: size,
        })
    }

    /// Bind-group entries for the map array and its linear and nearest
    /// samplers at bindings `first`, `first + 1` and `first + 2`: the
    /// scene's group ([`crate::render::scene_buffers::SCENE_LAYOUT`]) is
    /// their one user.
    pub fn bind_group_entries(&self, first: u32) -> [wgpu::BindGroupEntry<'_>; 3] {
        [
            wgpu::BindGroupEntry {
                binding: first,
                resource: wgpu::BindingResource::TextureView(&self.view),
            },
            wgpu::BindGroupEntry {
                binding: first + 1,
                resource: wgpu::BindingResource::Sampler(&self.linear),
            },
            wgpu::BindGroupEntry {
                binding: first + 2,
                resource: wgpu::BindingResource::Sampler(&self.nearest),
            },
        ]
    }

    /// Map word of each of `mesh`'s own textures: its array layer with its
    /// sampler's bits (see [`MAP_LAYER_MASK`]).
    pub fn mesh_layers(&self, mesh: &crate::scene::Mesh) -> Vec<u32> {
        mesh.textures
            .iter()
            .enumerate()
            .map(|(i, t)| match self.layer_of(t) {
                Some(layer) => layer | mesh.texture_samplers.get(i).map_or(0, map_sampler_bits),
                None => NO_TEXTURE,
            })
            .collect()
    }

    /// The GPU layer of each vertex's own map ([`NO_TEXTURE`] for none).
    pub fn vertex_layer(layers: &[u32], mesh: &crate::scene::Mesh, vertex: usize) -> u32 {
        mesh.vertex_textures
            .get(vertex)
            .and_then(|&t| layers.get(t as usize))
            .copied()
            .unwrap_or(NO_TEXTURE)
    }

    /// The array layer of `texture`, if the scene uses it.
    pub fn layer_of(&self, texture: &Arc<Texture>) -> Option<u32> {
        self.layers
            .iter()
            .position(|t| Arc::ptr_eq(t, texture) || **t == **texture)
            .map(|i| i as u32)
    }
}

fn linear_to_srgb(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Level 0 at `size` x `size` (the image resampled when its size differs:
/// nearest when enlarging by a whole factor, so texel blocks stay exact,
/// bilinear otherwise), then each level half the last by a 2x2 box filter
/// in linear light, down to 1x1. Returns (edge, sRGB RGBA8 texels) per level.
pub fn mip_chain(image: &Texture, size: u32) -> Vec<(u32, Vec<u8>)> {
    let base: Vec<u8> = if image.width == size && image.height == size {
        image.rgba8.clone()
    } else {
        let buffer = image::RgbaImage::from_raw(image.width, image.height, image.rgba8.clone())
            .unwrap_or_else(|| image::RgbaImage::new(1, 1));
        let whole = size.is_multiple_of(image.width) && size.is_multiple_of(image.height);
        let filter = if whole {
            image::imageops::FilterType::Nearest
        } else {
            image::imageops::FilterType::Triangle
        };
        image::imageops::resize(&buffer, size, size, filter).into_raw()
    };
    let mut levels = Vec::new();
    let mut prev_edge = size;
    let mut prev = base;
    while prev_edge > 1 {
        let next = (prev_edge / 2).max(1);
        let mut texels = vec![0u8; (next * next * 4) as usize];
        for y in 0..next {
            for x in 0..next {
                let mut sum = [0.0f32; 4];
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let sx = (2 * x + dx).min(prev_edge - 1);
                    let sy = (2 * y + dy).min(prev_edge - 1);
                    let i = ((sy * prev_edge + sx) * 4) as usize;
                    for c in 0..3 {
                        sum[c] += srgb_to_linear(prev[i + c]);
                    }
                    sum[3] += f32::from(prev[i + 3]) / 255.0;
                }
                let o = ((y * next + x) * 4) as usize;
                for c in 0..3 {
                    texels[o + c] = linear_to_srgb(sum[c] / 4.0);
                }
                texels[o + 3] = (sum[3] / 4.0 * 255.0 + 0.5) as u8;
            }
        }
        levels.push((prev_edge, std::mem::replace(&mut prev, texels)));
        prev_edge = next;
    }
    levels.push((prev_edge, prev));
    levels
}
