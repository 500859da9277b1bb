//! Pass 3b (temporal accumulation while the view moves): blends this
//! frame's sample into the previous frame's image, reprojected along each
//! pixel's motion vector (see `shaders/reproject.wgsl`).
//!
//! A moving frame runs: [`ReprojectPass::encode_snapshot`] (the previous
//! frame's accumulator and G-buffer depth and ids become the history, and
//! the accumulator is cleared so the accumulate pass writes this sample
//! alone), the usual raster / trace / accumulate passes, then
//! [`ReprojectPass::encode`] (the blend, copied back into the accumulator,
//! which the resolve pass shows as usual).
//!
//! It reads no scene: its one group is [`PASS_LAYOUT`].

use crate::gpu::layout::{
    read_only_storage_entry, read_write_storage_entry, texture_entry, uniform_entry,
};
use crate::gpu::twins::{ReprojectUniforms, REPROJECT_WORKGROUP};
use crate::gpu::{shader, Gpu, GpuError};
use crate::render::targets::{Targets, ID_FORMAT, NORMAL_DEPTH_FORMAT};

/// The previous frame's image and surfaces, and this frame's output.
struct History {
    width: u32,
    height: u32,
    /// The previous frame's accumulator: colour sum, sample count.
    color: wgpu::Buffer,
    /// The previous frame's G-buffer view depth (w) and object ids.
    normal_depth: wgpu::Texture,
    id: wgpu::Texture,
    /// This frame's blend, copied into the accumulator after the pass.
    blended: wgpu::Buffer,
    /// Motion vectors in pixels: where each pixel's surface moved since the
    /// previous frame (current minus previous position).
    motion: wgpu::Buffer,
}

pub struct ReprojectPass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    history: Option<History>,
    bind_groups: Option<[wgpu::BindGroup; 2]>,
}

const C: wgpu::ShaderStages = wgpu::ShaderStages::COMPUTE;
const FLOAT: wgpu::TextureSampleType = wgpu::TextureSampleType::Float { filterable: false };
const UINT: wgpu::TextureSampleType = wgpu::TextureSampleType::Uint;

/// The reproject pass's one group (it reads no scene), binding by binding
/// as `shaders/reproject.wgsl` declares it.
pub const PASS_LAYOUT: [wgpu::BindGroupLayoutEntry; 10] = [
    uniform_entry(0, C),           // frame
    uniform_entry(1, C),           // params
    texture_entry(2, FLOAT),       // normal_depth_tex
    texture_entry(3, UINT),        // id_tex
    read_only_storage_entry(4, C), // current
    read_only_storage_entry(5, C), // history
    texture_entry(6, FLOAT),       // history_normal_depth
    texture_entry(7, UINT),        // history_id
    read_write_storage_entry(8),   // blended
    read_write_storage_entry(9),   // motion
];

impl ReprojectPass {
    pub fn new(gpu: &Gpu) -> Result<ReprojectPass, GpuError> {
        let module = shader::create_module(gpu, "reproject.wgsl")?;
        gpu.scoped(|| {
            let layout = gpu
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("reproject bind group layout"),
                    entries: &PASS_LAYOUT,
                });
            let pipeline_layout =
                gpu.device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("reproject pipeline layout"),
                        bind_group_layouts: &[Some(&layout)],
                        immediate_size: 0,
                    });
            let pipeline = gpu
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("reproject pipeline"),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: Default::default(),
                    cache: None,
                });
            let params = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("reproject uniforms"),
                size: std::mem::size_of::<ReprojectUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            ReprojectPass {
                pipeline,
                layout,
                params,
                history: None,
                bind_groups: None,
            }
        })
    }

    /// (Re)creates the history at the targets' size and binds it, with the
    /// frame uniforms and both G-buffers (raster and traced).
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        frame: &wgpu::Buffer,
        targets: &Targets,
    ) -> Result<(), GpuError> {
        let (w, h) = (targets.width, targets.height);
        if self
            .history
            .as_ref()
            .is_none_or(|hist| (hist.width, hist.height) != (w, h))
        {
            self.history = Some(gpu.scoped(|| new_history(gpu, w, h))?);
        }
        let Some(hist) = &self.history else {
            return Ok(());
        };
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (hist_nd, hist_id) = (view(&hist.normal_depth), view(&hist.id));
        let group = |label, normal_depth: &wgpu::Texture, id: &wgpu::Texture| {
            let (nd, id) = (view(normal_depth), view(id));
            gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: frame.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: self.params.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&nd),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: wgpu::BindingResource::TextureView(&id),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: targets.accum.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 5,
                        resource: hist.color.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 6,
                        resource: wgpu::BindingResource::TextureView(&hist_nd),
                    },
                    wgpu::BindGroupEntry {
                        binding: 7,
                        resource: wgpu::BindingResource::TextureView(&hist_id),
                    },
                    wgpu::BindGroupEntry {
                        binding: 8,
                        resource: hist.blended.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 9,
                        resource: hist.motion.as_entire_binding(),
                    },
                ],
            })
        };
        self.bind_groups = Some([
            group(
                "reproject bind group (raster)",
                &targets.raster.normal_depth,
                &targets.raster.id,
            ),
            group(
                "reproject bind group (traced)",
                &targets.traced.normal_depth,
                &targets.traced.id,
            ),
        ]);
        Ok(())
    }

    /// Writes this frame's uniforms (camera matrices, rejection settings).
    pub fn write_uniforms(&self, gpu: &Gpu, uniforms: &ReprojectUniforms) {
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(uniforms));
    }

    /// Before this frame's passes: the accumulator and the G-buffer (still
    /// the previous frame's) become the history; the accumulator is cleared.
    pub fn encode_snapshot(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        traced: bool,
    ) {
        let Some(hist) = &self.history else {
            return;
        };
        encoder.copy_buffer_to_buffer(&targets.accum, 0, &hist.color, 0, targets.accum.size());
        if traced {
            // From the trace pass's buffers: the traced textures hold the
            // last frame only where a reproject pass followed it.
            (targets.traced_output).encode_copy(encoder, &hist.normal_depth, &hist.id);
        } else {
            let extent = wgpu::Extent3d {
                width: hist.width,
                height: hist.height,
                depth_or_array_layers: 1,
            };
            let g = &targets.raster;
            for (from, to) in [(&g.normal_depth, &hist.normal_depth), (&g.id, &hist.id)] {
                encoder.copy_texture_to_texture(from.as_image_copy(), to.as_image_copy(), extent);
            }
        }
        encoder.clear_buffer(&targets.accum, 0, None);
    }

    /// After the accumulate pass: the blend, then copied into the accumulator.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        traced: bool,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let Some(hist) = &self.history else {
            return;
        };
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("reproject pass"),
                timestamp_writes,
            });
            pass.set_pipeline(&self.pipeline);
            let groups = self.bind_groups.as_ref();
            pass.set_bind_group(0, groups.map(|g| &g[usize::from(traced)]), &[]);
            pass.dispatch_workgroups(
                targets.width.div_ceil(REPROJECT_WORKGROUP),
                targets.height.div_ceil(REPROJECT_WORKGROUP),
                1,
            );
        }
        encoder.copy_buffer_to_buffer(&hist.blended, 0, &targets.accum, 0, targets.accum.size());
    }

    /// The motion-vector buffer of the last moving frame (vec2<f32> per pixel).
    pub fn motion_buffer(&self) -> Option<&wgpu::Buffer> {
        self.history.as_ref().map(|h| &h.motion)
    }
}

fn new_history(gpu: &Gpu, width: u32, height: u32) -> History {
    let pixels = u64::from(width) * u64::from(height);
    let buffer = |label, bytes_per_pixel: u64, usage| {
        gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: pixels * bytes_per_pixel,
            usage: wgpu::BufferUsages::STORAGE | usage,
            mapped_at_creation: false,
        })
    };
    let texture = |label, format| {
        gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        })
    };
    History {
        width,
        height,
        color: buffer("history colour", 16, wgpu::BufferUsages::COPY_DST),
        normal_depth: texture("history normal+depth", NORMAL_DEPTH_FORMAT),
        id: texture("history id", ID_FORMAT),
        blended: buffer("temporal blend", 16, wgpu::BufferUsages::COPY_SRC),
        motion: buffer("motion vectors", 8, wgpu::BufferUsages::COPY_SRC),
    }
}
