//! Bind group layout entries and bind group entries, written once for every
//! pass. The entry builders are `const fn`, so each pass states its layout
//! as a `const` array that `tests/shaders.rs` reads without a GPU and checks
//! against the WGSL declarations (binding numbers and types).

/// A uniform buffer visible to `visibility`.
pub const fn uniform_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    buffer_entry(binding, visibility, wgpu::BufferBindingType::Uniform)
}

/// A read-only storage buffer visible to `visibility`.
pub const fn read_only_storage_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    buffer_entry(
        binding,
        visibility,
        wgpu::BufferBindingType::Storage { read_only: true },
    )
}

/// A read-write storage buffer for compute shaders.
pub const fn read_write_storage_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    buffer_entry(
        binding,
        wgpu::ShaderStages::COMPUTE,
        wgpu::BufferBindingType::Storage { read_only: false },
    )
}

const fn buffer_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BufferBindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A 2D texture read with textureLoad by compute shaders.
pub const fn texture_entry(
    binding: u32,
    sample_type: wgpu::TextureSampleType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// A write-only 2D storage texture for compute shaders.
pub const fn storage_texture_entry(
    binding: u32,
    format: wgpu::TextureFormat,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
}

/// The base-colour texture array (filterable, sampled).
pub const fn map_array_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: wgpu::TextureViewDimension::D2Array,
            multisampled: false,
        },
        count: None,
    }
}

/// A filtering sampler.
pub const fn sampler_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}

/// The one group of the benchmark's floor kernel (`shaders/bench_floor.wgsl`,
/// run by `celray bench`, outside the library): its parameters, the spheres
/// and the RGBA8 output. Here so that `tests/shaders.rs` can check it too.
pub const BENCH_FLOOR_LAYOUT: [wgpu::BindGroupLayoutEntry; 3] = [
    uniform_entry(0, wgpu::ShaderStages::COMPUTE),
    read_only_storage_entry(1, wgpu::ShaderStages::COMPUTE),
    read_write_storage_entry(2),
];

/// Bind group entries 0, 1, 2, ... binding whole buffers, in order.
pub fn buffer_entries<'a>(buffers: &[&'a wgpu::Buffer]) -> Vec<wgpu::BindGroupEntry<'a>> {
    buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect()
}
