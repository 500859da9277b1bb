//! Pass 3: add this sample's colour (with outlines) to the accumulator.
//! Group 0 is the scene's shared group (instances and materials give each
//! pixel's outline); group 1 is [`PASS_LAYOUT`] (frame uniforms, one
//! G-buffer, the accumulator).

use crate::gpu::layout::{read_write_storage_entry, texture_entry, uniform_entry};
use crate::gpu::twins::ACCUMULATE_WORKGROUP;
use crate::gpu::{shader, Gpu, GpuError};
use crate::render::scene_buffers::{scene_layout, SceneBuffers, PASS_GROUP, SCENE_GROUP};
use crate::render::targets::{GBuffer, Targets};

const FLOAT: wgpu::TextureSampleType = wgpu::TextureSampleType::Float { filterable: false };

/// Group 1 of the accumulate pass, binding by binding as
/// `shaders/accumulate.wgsl` declares it.
pub const PASS_LAYOUT: [wgpu::BindGroupLayoutEntry; 5] = [
    uniform_entry(0, wgpu::ShaderStages::COMPUTE), // frame
    texture_entry(1, FLOAT),                       // color_tex
    texture_entry(2, FLOAT),                       // normal_depth_tex
    texture_entry(3, wgpu::TextureSampleType::Uint), // id_tex
    read_write_storage_entry(4),                   // accum
];

pub struct AccumulatePass {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// The scene's shared group.
    scene_group: Option<wgpu::BindGroup>,
    bind_groups: Option<[wgpu::BindGroup; 2]>,
}

impl AccumulatePass {
    pub fn new(gpu: &Gpu) -> Result<AccumulatePass, GpuError> {
        let module = shader::create_module(gpu, "accumulate.wgsl")?;
        gpu.scoped(|| {
            let scene_layout = scene_layout(gpu);
            let layout = gpu
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("accumulate bind group layout"),
                    entries: &PASS_LAYOUT,
                });
            let pipeline_layout =
                gpu.device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("accumulate pipeline layout"),
                        bind_group_layouts: &[Some(&scene_layout), Some(&layout)],
                        immediate_size: 0,
                    });
            let pipeline = gpu
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("accumulate pipeline"),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: Default::default(),
                    cache: None,
                });
            AccumulatePass {
                pipeline,
                layout,
                scene_group: None,
                bind_groups: None,
            }
        })
    }

    /// Two bind groups: one reading the raster G-buffer (raster mode), one
    /// reading the traced G-buffer (hybrid and raytrace modes).
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        frame: &wgpu::Buffer,
        scene: &SceneBuffers,
        targets: &Targets,
    ) {
        let group = |label, g: &GBuffer| {
            let view = |t: &wgpu::Texture| t.create_view(&Default::default());
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
                        resource: wgpu::BindingResource::TextureView(&view(&g.color)),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&view(&g.normal_depth)),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: wgpu::BindingResource::TextureView(&view(&g.id)),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: targets.accum.as_entire_binding(),
                    },
                ],
            })
        };
        self.scene_group = Some(scene.bind_group.clone());
        self.bind_groups = Some([
            group("accumulate bind group (raster)", &targets.raster),
            group("accumulate bind group (traced)", &targets.traced),
        ]);
    }

    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        traced: bool,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("accumulate pass"),
            timestamp_writes,
        });
        pass.set_pipeline(&self.pipeline);
        let groups = self.bind_groups.as_ref();
        pass.set_bind_group(SCENE_GROUP, self.scene_group.as_ref(), &[]);
        pass.set_bind_group(PASS_GROUP, groups.map(|g| &g[usize::from(traced)]), &[]);
        pass.dispatch_workgroups(
            targets.width.div_ceil(ACCUMULATE_WORKGROUP),
            targets.height.div_ceil(ACCUMULATE_WORKGROUP),
            1,
        );
    }
}
