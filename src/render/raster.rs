//! Pass 1: rasterize into the raster G-buffer, shaded: every instance in
//! raster mode, the meshes in hybrid mode (analytic shapes and CSG are
//! traced), nothing in raytrace mode (the pass only clears). Group 0 is
//! the scene's shared group; group 1 is [`PASS_LAYOUT`] (frame uniforms).

use std::collections::HashMap;

use glam::{Mat3, Vec3};

use crate::gpu::twins::{Vertex, FAR_DEPTH};
use crate::gpu::uniform_tables::UniformTables;
use crate::gpu::{shader, Gpu, GpuError};
use crate::render::camera::SampleCamera;
use crate::render::scene_buffers::{
    scene_layout, Cull, Draw, LightLayout, MeshLevel, SceneBuffers, ShadingVariant, PASS_GROUP,
    SCENE_GROUP,
};
use crate::render::settings::RenderMode;
use crate::render::targets::{
    Targets, ALBEDO_FORMAT, COLOR_FORMAT, DEPTH_FORMAT, ID_FORMAT, NORMAL_DEPTH_FORMAT,
};
use crate::scene::{Camera, Scene, Shape, MAX_SILHOUETTE_ERROR_PX};

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
pub struct RasterVariant {
    /// The texture code (entry points `vs_textured`/`fs_textured` rather
    /// than `vs_main`/`fs_main`).
    textures: bool,
    /// What the materials and lights need of the shading code.
    shading: ShadingVariant,
    /// The lights' count and kinds, when fixed.
    lights: LightLayout,
    /// The tables read from their uniform copies.
    tables: UniformTables,
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

    /// The variant `scene` (uploaded as `buffers`) needs.
    pub fn variant_of(scene: &Scene, buffers: &SceneBuffers) -> RasterVariant {
        RasterVariant {
            textures: buffers.uses_textures,
            shading: ShadingVariant::of(&scene.materials, &scene.lights),
            lights: LightLayout::of(&scene.lights),
            tables: buffers.tables,
        }
    }

    /// The variant the pass draws with now.
    pub fn variant(&self) -> RasterVariant {
        self.variant
    }

    /// Whether the pass has built `variant`'s pipelines.
    pub fn has_variant(&self, variant: RasterVariant) -> bool {
        self.pipelines.contains_key(&variant)
    }

    /// Builds the pipelines of `variant` (once) and binds the frame
    /// uniforms (the scene's group is the scene's own). Called again when
    /// materials or lights change: they choose the variant
    /// ([`RasterPass::variant_of`]).
    pub fn prepare(&mut self, gpu: &Gpu, frame: &wgpu::Buffer, variant: RasterVariant) {
        self.variant = variant;
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

    /// Clears the G-buffer to `background` and draws what `draws` selects.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        scene: &SceneBuffers,
        background: [f32; 3],
        draws: &RasterDraws,
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
        let Some(pipelines) = self.pipelines.get(&self.variant) else {
            return;
        };
        for (d, level) in draws.selected(scene) {
            pass.set_pipeline(
                &pipelines[match d.cull {
                    Cull::Back => 0,
                    Cull::Front => 1,
                    Cull::None => 2,
                }],
            );
            pass.draw_indexed(
                level.first_index..level.first_index + level.index_count,
                level.base_vertex,
                d.instances.clone(),
            );
        }
    }
}

/// What the raster pass draws of a scene for one sample.
#[derive(Debug, Clone, Default)]
pub struct RasterDraws {
    /// Raster mode draws everything; hybrid only meshes (the trace pass
    /// finds analytic shapes exactly); raytrace nothing (only the clears).
    pub mode: RenderMode,
    /// The level of detail of each of the scene's draws ([`draw_levels`]);
    /// missing entries draw the finest.
    pub levels: Vec<usize>,
}

impl RasterDraws {
    /// The draws to make, each with its level's triangles.
    fn selected<'a>(
        &'a self,
        scene: &'a SceneBuffers,
    ) -> impl Iterator<Item = (&'a Draw, MeshLevel)> + 'a {
        scene
            .draws
            .iter()
            .enumerate()
            .filter(|(_, d)| match self.mode {
                RenderMode::Raster => true,
                RenderMode::Hybrid => d.is_mesh,
                RenderMode::Raytrace => false,
            })
            .map(|(i, d)| {
                let level = self.levels.get(i).copied().unwrap_or(0);
                (d, d.levels[level.min(d.levels.len() - 1)])
            })
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
    let mut constants = variant.shading.constants().to_vec();
    constants.extend(variant.lights.constants());
    constants.push(variant.tables.constant());
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

/// What choosing a level of detail needs of one sample's camera.
#[derive(Debug, Clone, Copy)]
pub struct LodView {
    eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    /// Pixels per unit of tan(angle off the view axis): (height / 2) /
    /// tan(fov_y / 2).
    px_per_tan: f32,
    /// The tangents (x, y) of the frustum's corner, widened by the lens
    /// shear of depth of field: nothing outside is seen.
    corner_tan: (f32, f32),
}

impl LodView {
    /// The view of `sample`, taken by `camera` (at the sample's shutter
    /// time) on an image of `size` pixels.
    pub fn new(camera: &Camera, sample: &SampleCamera, size: (u32, u32)) -> LodView {
        let tan_half = (camera.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = size.0 as f32 / size.1.max(1) as f32;
        let shear = camera.aperture_radius / camera.resolved_focus_distance();
        let right = sample.forward.cross(camera.up).normalize_or_zero();
        LodView {
            eye: sample.eye,
            forward: sample.forward,
            right,
            up: right.cross(sample.forward),
            px_per_tan: size.1 as f32 * 0.5 / tan_half,
            corner_tan: (tan_half * aspect + shear, tan_half + shear),
        }
    }

    /// The most a short world-space offset on a sphere (centre `centre`,
    /// radius `rho`) can move on screen, in pixels per world unit, or None
    /// where the sphere reaches the eye's plane. At view-space point
    /// (x, y, z) the projection's Jacobian is (px_per_tan / z) [[1, 0,
    /// -x/z], [0, 1, -y/z]], whose largest singular value is (px_per_tan /
    /// z) sqrt(1 + (x/z)^2 + (y/z)^2); over the sphere, z >= z_min and
    /// |x/z| <= (|x_c| + rho) / z_min (and the frustum's corner bounds both
    /// tangents, nothing beyond being seen).
    fn px_per_unit(&self, centre: Vec3, rho: f32) -> Option<f32> {
        let c = centre - self.eye;
        let z_min = c.dot(self.forward) - rho;
        if z_min <= 0.0 {
            return None;
        }
        let tx = ((c.dot(self.right).abs() + rho) / z_min).min(self.corner_tan.0);
        let ty = ((c.dot(self.up).abs() + rho) / z_min).min(self.corner_tan.1);
        Some(self.px_per_tan / z_min * (1.0 + tx * tx + ty * ty).sqrt())
    }
}

/// The level of detail of each of `scene.draws` for one sample (an index
/// into its `levels`, 0 the finest): the coarsest level at which no
/// instance of the draw has its silhouette stray from the true surface by
/// more than [`MAX_SILHOUETTE_ERROR_PX`].
///
/// A sphere's level reaching `inset` inside it (`inset * s` in world
/// units, s the largest stretch of the instance's matrix) has its
/// silhouette within that distance of the true one, which
/// [`LodView::px_per_unit`] turns into pixels. A sphere reaching the eye's
/// plane is drawn at the finest level. `time` is the sample's shutter time
/// when instances move.
pub fn draw_levels(
    buffers: &SceneBuffers,
    scene: &Scene,
    view: &LodView,
    time: Option<f32>,
) -> Vec<usize> {
    buffers
        .draws
        .iter()
        .map(|d| {
            let radius = match scene.shapes[d.shape] {
                Shape::Sphere { radius } if d.levels.len() > 1 => radius,
                _ => return 0,
            };
            let mut level = d.levels.len() - 1;
            for gpu_index in d.instances.clone() {
                let inst = &scene.instances[buffers.instance_order[gpu_index as usize]];
                let m = time.map_or(inst.world_from_object, |t| inst.world_from_object_at(t));
                let stretch = max_stretch(Mat3::from_mat4(m));
                let Some(px_per_unit) = view.px_per_unit(m.w_axis.truncate(), radius * stretch)
                else {
                    return 0;
                };
                while level > 0
                    && d.levels[level].inset * stretch * px_per_unit > MAX_SILHOUETTE_ERROR_PX
                {
                    level -= 1;
                }
                if level == 0 {
                    break;
                }
            }
            level
        })
        .collect()
}

/// An upper bound on how much `m` stretches any vector: the square root of
/// the largest row sum of |m^T m| (Gershgorin), which is exact for a
/// rotation after an axis-aligned scale.
fn max_stretch(m: Mat3) -> f32 {
    let g = m.transpose() * m;
    let row = |i: usize| g.x_axis[i].abs() + g.y_axis[i].abs() + g.z_axis[i].abs();
    row(0).max(row(1)).max(row(2)).sqrt()
}
