//! Pass 2: ray tracing in compute. Per pixel, the same primary ray as the
//! raster pass, traced through the two-level BVH (analytic shapes only in
//! hybrid mode, composited against the raster depth; everything in raytrace
//! mode), then shadow rays and mirror reflections against the whole scene.

use wgpu::util::DeviceExt;

use crate::gpu::layout::{
    buffer_entries, read_only_storage_entry, read_write_storage_entry, storage_texture_entry,
    texture_entry, uniform_entry,
};
use crate::gpu::timer::PassTimer;
use crate::gpu::twins::TRACE_WORKGROUP;
use crate::gpu::{readback, shader, Gpu, GpuError};
use crate::render::scene_buffers::SceneBuffers;
use crate::render::targets::{Targets, COLOR_FORMAT, ID_FORMAT, NORMAL_DEPTH_FORMAT};

pub struct TracePass {
    /// Built with the CSG code removed (`CSG_ENABLED = false`).
    pipeline: wgpu::ComputePipeline,
    /// With CSG, built the first time a scene with CSG shapes is prepared.
    csg_pipeline: Option<wgpu::ComputePipeline>,
    use_csg: bool,
    module: wgpu::ShaderModule,
    pipeline_layout: wgpu::PipelineLayout,
    scene_layout: wgpu::BindGroupLayout,
    target_layout: wgpu::BindGroupLayout,
    bind_groups: Option<(wgpu::BindGroup, wgpu::BindGroup)>,
    /// Counters the shader bumps: [0] = pixels that ran out of traversal steps.
    stats: wgpu::Buffer,
}

/// The trace pipeline with or without the CSG code (override `CSG_ENABLED`).
fn trace_pipeline(
    gpu: &Gpu,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    csg: bool,
) -> wgpu::ComputePipeline {
    gpu.device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(if csg {
                "trace pipeline (CSG)"
            } else {
                "trace pipeline"
            }),
            layout: Some(layout),
            module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &[("CSG_ENABLED", f64::from(u8::from(csg)))],
                ..Default::default()
            },
            cache: None,
        })
}

impl TracePass {
    pub fn new(gpu: &Gpu) -> Result<TracePass, GpuError> {
        let module = shader::create_module(gpu, "trace.wgsl")?;
        let c = wgpu::ShaderStages::COMPUTE;
        gpu.scoped(|| {
            let scene_layout =
                gpu.device
                    .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                        label: Some("trace scene layout"),
                        entries: &[
                            uniform_entry(0, c),
                            read_only_storage_entry(1, c),
                            read_only_storage_entry(2, c),
                            read_only_storage_entry(3, c),
                            read_only_storage_entry(4, c),
                            read_only_storage_entry(5, c),
                            read_only_storage_entry(6, c),
                            read_only_storage_entry(7, c),
                            read_write_storage_entry(8),
                            // CSG programs and leaves (shaders/lib/csg.wgsl).
                            read_only_storage_entry(9, c),
                            read_only_storage_entry(10, c),
                        ],
                    });
            let float = wgpu::TextureSampleType::Float { filterable: false };
            let target_layout =
                gpu.device
                    .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                        label: Some("trace target layout"),
                        entries: &[
                            texture_entry(0, float),
                            texture_entry(1, wgpu::TextureSampleType::Uint),
                            storage_texture_entry(2, COLOR_FORMAT),
                            storage_texture_entry(3, NORMAL_DEPTH_FORMAT),
                            storage_texture_entry(4, ID_FORMAT),
                        ],
                    });
            let layout = gpu
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("trace pipeline layout"),
                    bind_group_layouts: &[Some(&scene_layout), Some(&target_layout)],
                    immediate_size: 0,
                });
            let pipeline = trace_pipeline(gpu, &layout, &module, false);
            let stats = gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("trace stats"),
                    contents: &[0u8; 16],
                    usage: wgpu::BufferUsages::STORAGE
                        | wgpu::BufferUsages::COPY_SRC
                        | wgpu::BufferUsages::COPY_DST,
                });
            TracePass {
                pipeline,
                csg_pipeline: None,
                use_csg: false,
                module,
                pipeline_layout: layout,
                scene_layout,
                target_layout,
                bind_groups: None,
                stats,
            }
        })
    }

    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        frame: &wgpu::Buffer,
        scene: &SceneBuffers,
        targets: &Targets,
    ) {
        self.use_csg = !scene.accel.csg_ops.is_empty();
        if self.use_csg && self.csg_pipeline.is_none() {
            self.csg_pipeline = Some(trace_pipeline(
                gpu,
                &self.pipeline_layout,
                &self.module,
                true,
            ));
        }
        let buffers = [
            frame,
            &scene.instances,
            &scene.materials,
            &scene.lights,
            &scene.shapes,
            &scene.nodes,
            &scene.triangles,
            &scene.tlas_items,
            &self.stats,
            &scene.csg_ops,
            &scene.csg_leaves,
        ];
        let entries = buffer_entries(&buffers);
        let scene_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace scene bind group"),
            layout: &self.scene_layout,
            entries: &entries,
        });
        let views = [
            &targets.raster.normal_depth,
            &targets.raster.id,
            &targets.traced.color,
            &targets.traced.normal_depth,
            &targets.traced.id,
        ]
        .map(|t| t.create_view(&Default::default()));
        let entries: Vec<wgpu::BindGroupEntry> = views
            .iter()
            .enumerate()
            .map(|(i, v)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: wgpu::BindingResource::TextureView(v),
            })
            .collect();
        let target_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace target bind group"),
            layout: &self.target_layout,
            entries: &entries,
        });
        self.bind_groups = Some((scene_group, target_group));
    }

    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        timer: Option<&PassTimer>,
    ) {
        let Some((scene_group, target_group)) = &self.bind_groups else {
            return;
        };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("trace pass"),
            timestamp_writes: timer.map(|t| t.compute_writes("trace")),
        });
        match (&self.csg_pipeline, self.use_csg) {
            (Some(csg), true) => pass.set_pipeline(csg),
            _ => pass.set_pipeline(&self.pipeline),
        }
        pass.set_bind_group(0, scene_group, &[]);
        pass.set_bind_group(1, target_group, &[]);
        pass.dispatch_workgroups(
            targets.width.div_ceil(TRACE_WORKGROUP),
            targets.height.div_ceil(TRACE_WORKGROUP),
            1,
        );
    }

    /// Pixels (summed over samples) whose traversal ran out of its step
    /// budget since this pass was created: 0 unless the scene is too deep.
    pub fn overflow_pixels(&self, gpu: &Gpu) -> Result<u32, GpuError> {
        let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("trace stats readback"),
            size: 16,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.stats, 0, &staging, 0, 16);
        gpu.queue.submit([encoder.finish()]);
        let bytes = readback::read_buffer(gpu, &staging)?;
        Ok(bytemuck::cast_slice::<u8, u32>(&bytes)[0])
    }
}
