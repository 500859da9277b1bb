//! Pass 1: rasterize into the raster G-buffer, shaded: every instance in
//! raster mode, the meshes in hybrid mode (analytic shapes and CSG are
//! traced), nothing in raytrace mode (the pass only clears). Group 0 is
//! the scene's shared group; group 1 is [`PASS_LAYOUT`] (frame uniforms).

use std::collections::HashMap;

use crate::gpu::twins::{Vertex, FAR_DEPTH};
use crate::gpu::{shader, Gpu, GpuError};
use crate::render::scene_buffers::{
    scene_layout, Cull, SceneBuffers, ShadingVariant, PASS_GROUP, SCENE_GROUP,
};
use crate::render::settings::RenderMode;
use crate::render::targets::{
    Targets, ALBEDO_FORMAT, COLOR_FORMAT, DEPTH_FORMAT, ID_FORMAT, NORMAL_DEPTH_FORMAT,
};

pub struct RasterPass {
    /// One pipeline per [`Cull`] mode (back, front, none) for each
    /// [`RasterVariant`] a scene has needed, built the first time.
    pipelines: HashMap<RasterVariant, [wgpu::RenderPipeline; 3]>,
    variant: RasterVariant,
    module: wgpu::ShaderModule,
    pipeline_layout: wgpu::PipelineLayout,
    layout: wgpu::BindGroupLayout,
    bind_group: Option<wgpu::BindGroup>,
}

use crate::gpu::layout::uniform_entry;

/// What a scene needs compiled into the raster shaders.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
struct RasterVariant {
    /// The texture code (entry points `vs_textured`/`fs_textured` rather
    /// than `vs_main`/`fs_main`).
    textures: bool,
    /// What the materials and lights need of the shading code.
    shading: ShadingVariant,
}

/// Group 1 of the raster pass, binding by binding as `shaders/raster.wgsl`
/// declares it.
pub const PASS_LAYOUT: [wgpu::BindGroupLayoutEntry; 1] = [
    uniform_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT), // frame
];

impl RasterPass {
    pub fn new(gpu: &Gpu) -> Result<RasterPass, GpuError> {
        let module = shader::create_module(gpu, "raster.wgsl")?;
        gpu.scoped(|| {
            let scene_layout = scene_layout(gpu);
            let layout = gpu
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some("raster bind group layout"),
                    entries: &PASS_LAYOUT,
                });
            let pipeline_layout =
                gpu.device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some("raster pipeline layout"),
                        bind_group_layouts: &[Some(&scene_layout), Some(&layout)],
                        immediate_size: 0,
                    });
            RasterPass {
                pipelines: HashMap::new(),
                variant: RasterVariant::default(),
                module,
                pipeline_layout,
                layout,
                bind_group: None,
            }
        })
    }

    /// Builds the pipelines the scene needs (once) and binds the frame
    /// uniforms (the scene's group is the scene's own). Called again when
    /// materials or lights change: they choose the shading variant.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        frame: &wgpu::Buffer,
        scene: &SceneBuffers,
        shading: ShadingVariant,
    ) {
        self.variant = RasterVariant {
            textures: scene.uses_textures,
            shading,
        };
        if !self.pipelines.contains_key(&self.variant) {
            let built = raster_pipelines(gpu, &self.pipeline_layout, &self.module, self.variant);
            self.pipelines.insert(self.variant, built);
        }
        let entries = [wgpu::BindGroupEntry {
            binding: 0,
            resource: frame.as_entire_binding(),
        }];
        self.bind_group = Some(gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raster bind group"),
            layout: &self.layout,
            entries: &entries,
        }));
    }

    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        scene: &SceneBuffers,
        background: [f32; 3],
        mode: RenderMode,
        timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) {
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (color, normal_depth, id, albedo, depth) = (
            view(&targets.raster.color),
            view(&targets.raster.normal_depth),
            view(&targets.raster.id),
            view(&targets.raster_albedo),
            view(&targets.depth),
        );
        let clear = |c: wgpu::Color| wgpu::Operations {
            load: wgpu::LoadOp::Clear(c),
            store: wgpu::StoreOp::Store,
        };
        let attachment = |v, c| {
            Some(wgpu::RenderPassColorAttachment {
                view: v,
                depth_slice: None,
                resolve_target: None,
                ops: clear(c),
            })
        };
        let bg = wgpu::Color {
            r: f64::from(background[0]),
            g: f64::from(background[1]),
            b: f64::from(background[2]),
            a: 1.0,
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("raster pass"),
            color_attachments: &[
                attachment(&color, bg),
                attachment(
                    &normal_depth,
                    wgpu::Color {
                        r: 0.0,
                        g: 0.0,
                        b: 0.0,
                        a: f64::from(FAR_DEPTH),
                    },
                ),
                attachment(&id, wgpu::Color::TRANSPARENT),
                if self.variant.textures {
                    attachment(&albedo, wgpu::Color::TRANSPARENT)
                } else {
                    None
                },
            ],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(SCENE_GROUP, &scene.bind_group, &[]);
        pass.set_bind_group(PASS_GROUP, self.bind_group.as_ref(), &[]);
        pass.set_vertex_buffer(0, scene.vertices.slice(..));
        pass.set_index_buffer(scene.indices.slice(..), wgpu::IndexFormat::Uint32);
        // Raster mode draws everything; hybrid only meshes (the trace pass
        // finds analytic shapes exactly); raytrace nothing (only the clears).
        let drawn = |d: &&crate::render::scene_buffers::Draw| match mode {
            RenderMode::Raster => true,
            RenderMode::Hybrid => d.is_mesh,
            RenderMode::Raytrace => false,
        };
        let Some(pipelines) = self.pipelines.get(&self.variant) else {
            return;
        };
        for d in scene.draws.iter().filter(drawn) {
            pass.set_pipeline(
                &pipelines[match d.cull {
                    Cull::Back => 0,
                    Cull::Front => 1,
                    Cull::None => 2,
                }],
            );
            pass.draw_indexed(
                d.first_index..d.first_index + d.index_count,
                d.base_vertex,
                d.instances.clone(),
            );
        }
    }
}

/// The three cull-mode pipelines of one variant.
fn raster_pipelines(
    gpu: &Gpu,
    pipeline_layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    variant: RasterVariant,
) -> [wgpu::RenderPipeline; 3] {
    let textures = variant.textures;
    let constants = variant.shading.constants();
    let options = || wgpu::PipelineCompilationOptions {
        constants: &constants,
        ..Default::default()
    };
    // Untextured scenes run the entry points without texture varyings.
    let (vs, fs) = if textures {
        ("vs_textured", "fs_textured")
    } else {
        ("vs_main", "fs_main")
    };
    let target = |format| {
        Some(wgpu::ColorTargetState {
            format,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        })
    };
    let pipeline = |cull_mode| {
        gpu.device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("raster pipeline"),
                layout: Some(pipeline_layout),
                vertex: wgpu::VertexState {
                    module,
                    entry_point: Some(vs),
                    compilation_options: options(),
                    buffers: &[Some(Vertex::LAYOUT)],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    front_face: wgpu::FrontFace::Ccw,
                    cull_mode,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module,
                    entry_point: Some(fs),
                    compilation_options: options(),
                    targets: &[
                        target(COLOR_FORMAT),
                        target(NORMAL_DEPTH_FORMAT),
                        target(ID_FORMAT),
                        // Only textured scenes' trace pass reads the albedo.
                        if textures {
                            target(ALBEDO_FORMAT)
                        } else {
                            None
                        },
                    ],
                }),
                multiview_mask: None,
                cache: None,
            })
    };
    [
        pipeline(Some(wgpu::Face::Back)),
        pipeline(Some(wgpu::Face::Front)),
        pipeline(None),
    ]
}
