//! Pass 4: the accumulator's average, tone mapped, into a colour target of
//! one format (a window's view image, the capture texture). The
//! [`crate::render::Renderer`] owns one per format it is asked for and keeps
//! each bound to its current accumulator and settings: outside the renderer,
//! resolve with [`crate::render::Renderer::resolve_into`].

use std::collections::HashMap;

use wgpu::util::DeviceExt;

use crate::gpu::layout::{buffer_entries, read_only_storage_entry, uniform_entry};
use crate::gpu::{shader, Gpu, GpuError};
use crate::render::settings::{RenderSettings, ToneMap};
use crate::render::targets::Targets;

/// The resolve pass's one group, binding by binding as
/// `shaders/resolve.wgsl` declares it.
pub const PASS_LAYOUT: [wgpu::BindGroupLayoutEntry; 2] = [
    uniform_entry(0, wgpu::ShaderStages::FRAGMENT),
    read_only_storage_entry(1, wgpu::ShaderStages::FRAGMENT),
];

pub struct ResolvePass {
    /// One pipeline per tone map a setting has asked for (built the first
    /// time): the tone map and the sRGB encoding are override constants,
    /// not uniforms, so the fragment shader holds only their code (a
    /// branch on a uniform costs the CPU driver about 2 ms of 6 here,
    /// docs/performance-history.md).
    pipelines: HashMap<ToneMap, wgpu::RenderPipeline>,
    /// The tone map of the current settings.
    tone_map: ToneMap,
    module: wgpu::ShaderModule,
    pipeline_layout: wgpu::PipelineLayout,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    format: wgpu::TextureFormat,
    bind_group: Option<wgpu::BindGroup>,
}

impl ResolvePass {
    /// A resolve pass drawing into targets of `format`.
    pub fn new(gpu: &Gpu, format: wgpu::TextureFormat) -> Result<ResolvePass, GpuError> {
        let module = shader::create_module(gpu, "resolve.wgsl")?;
        let settings = RenderSettings::default();
        gpu.scoped(|| {
            let layout = gpu
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("resolve bind group layout"),
                    entries: &PASS_LAYOUT,
                });
            let pipeline_layout =
                gpu.device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("resolve pipeline layout"),
                        bind_group_layouts: &[Some(&layout)],
                        immediate_size: 0,
                    });
            let params = gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("resolve uniforms"),
                    contents: bytemuck::bytes_of(&settings.to_gpu()),
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                });
            let mut pass = ResolvePass {
                pipelines: HashMap::new(),
                tone_map: settings.tone_map,
                module,
                pipeline_layout,
                layout,
                params,
                format,
                bind_group: None,
            };
            pass.build_pipeline(gpu);
            pass
        })
    }

    /// Builds the pipeline of the current tone map, unless built before.
    fn build_pipeline(&mut self, gpu: &Gpu) {
        if self.pipelines.contains_key(&self.tone_map) {
            return;
        }
        let constants = [
            ("TONE_MAP", f64::from(self.tone_map.to_gpu())),
            // Targets of an sRGB format encode as they store.
            ("ENCODE_SRGB", if self.format.is_srgb() { 0.0 } else { 1.0 }),
        ];
        let options = || wgpu::PipelineCompilationOptions {
            constants: &constants,
            ..Default::default()
        };
        let pipeline = gpu
            .device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("resolve pipeline"),
                layout: Some(&self.pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &self.module,
                    entry_point: Some("vs_main"),
                    compilation_options: options(),
                    buffers: &[],
                },
                primitive: Default::default(),
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &self.module,
                    entry_point: Some("fs_main"),
                    compilation_options: options(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: self.format,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            });
        self.pipelines.insert(self.tone_map, pipeline);
    }

    /// The format of the targets this pass draws into.
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// Binds `targets`' accumulator and takes `settings`' exposure and tone
    /// map (building that tone map's pipeline the first time).
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        settings: &RenderSettings,
        targets: &Targets,
    ) -> Result<(), GpuError> {
        self.tone_map = settings.tone_map;
        gpu.scoped(|| self.build_pipeline(gpu))?;
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&settings.to_gpu()));
        self.bind_group = Some(gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("resolve bind group"),
            layout: &self.layout,
            entries: &buffer_entries(&[&self.params, &targets.accum]),
        }));
        Ok(())
    }

    /// Draws the resolved image into `view` (which must be the accumulator's size).
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, view: &wgpu::TextureView) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("resolve pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                // The triangle covers every pixel: a clear first would
                // be a pass over the image's memory for nothing (on the
                // CPU driver a clear costs about what a write pass does).
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipelines[&self.tone_map]);
        pass.set_bind_group(0, self.bind_group.as_ref(), &[]);
        pass.draw(0..3, 0..1);
    }
}
