//! Pass 1: rasterize into the raster G-buffer, shaded: every instance in
//! raster mode, the meshes in hybrid mode (analytic shapes and CSG are
//! traced); in raytrace mode the renderer does not run it (nothing reads
//! its targets there: `Renderer::render_sample`). Group 0 is
//! the scene's shared group; group 1 is [`PASS_LAYOUT`] (frame uniforms).

use std::collections::HashMap;
use std::ops::Range;

use glam::{Mat3, Vec3};

use crate::gpu::twins::Vertex;
use crate::gpu::uniform_tables::UniformTables;
use crate::gpu::{shader, Gpu, GpuError};
use crate::render::camera::SampleCamera;
use crate::render::scene_buffers::{
    scene_layout, Cull, LightLayout, MeshLevel, SceneBuffers, ShadingVariant, PASS_GROUP,
    SCENE_GROUP,
};
use crate::render::settings::{RenderMode, RenderSettings, Temporal};
use crate::render::targets::{
    Targets, ALBEDO_FORMAT, COLOR_FORMAT, DEPTH_FORMAT, ID_FORMAT, NORMAL_DEPTH_FORMAT,
};
use crate::scene::{Camera, Scene, Shape, MAX_SILHOUETTE_ERROR_PX};

pub struct RasterPass {
    /// One pipeline per [`Cull`] mode (back, front, none) and draw
    /// direction ([`DrawCall::backward`]) for each [`RasterVariant`] a
    /// scene has needed, built the first time.
    pipelines: HashMap<RasterVariant, [wgpu::RenderPipeline; 6]>,
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
    /// Whether the fragments are shaded: in raster mode; in hybrid mode the
    /// trace pass shades every pixel, rasterized ones too, and reads only
    /// the normal, depth, id and albedo, so the colour goes unwritten (and
    /// untextured scenes run the geometry entry points of
    /// `shaders/raster.wgsl`).
    shade: bool,
    /// Whether the ids go in the colour's alpha, with no id target
    /// ([`ids_in_color`]).
    ids_in_color: bool,
}

impl RasterVariant {
    /// Whether the ids go in the colour's alpha ([`ids_in_color`]).
    pub fn ids_in_color(&self) -> bool {
        self.ids_in_color
    }
}

/// The most instances whose ids (instance + 1) a half float holds exactly:
/// every integer up to 2048.
pub const MAX_IDS_IN_COLOR: usize = 2048;

/// Whether raster mode writes each fragment's id into the colour target's
/// alpha (a half float, exact up to [`MAX_IDS_IN_COLOR`]) instead of an id
/// target of its own: on the CPU driver each colour target costs the
/// fragment path a share of its own, whatever its bytes (removing the id
/// target took the default scene's raster pass from 14.4 to 12.5 ms,
/// while an R16 id target saved nothing: docs/performance-history.md,
/// forty-second session). Implies raster mode. The outline marks and the
/// accumulate pass then read the ids there (`IDS_IN_COLOR`,
/// `shaders/lib/gbuffer.wgsl`). Not where the reproject pass runs
/// (temporal reprojection), which reads and keeps an id texture.
pub fn ids_in_color(instances: usize, settings: &RenderSettings) -> bool {
    settings.mode == RenderMode::Raster
        && settings.temporal == Temporal::Off
        && instances <= MAX_IDS_IN_COLOR
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

    /// The variant `scene` (uploaded as `buffers`) needs in `mode`.
    pub fn variant_of(
        scene: &Scene,
        buffers: &SceneBuffers,
        settings: &RenderSettings,
    ) -> RasterVariant {
        RasterVariant {
            textures: buffers.uses_textures,
            shading: ShadingVariant::of(scene),
            lights: LightLayout::of(&scene.lights),
            tables: buffers.tables,
            shade: settings.mode == RenderMode::Raster,
            ids_in_color: ids_in_color(scene.instances.len(), settings),
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

    /// Clears the G-buffer's colour (raster mode only) to `background`, its
    /// ids to 0 (the colour's alpha where [`ids_in_color`]) and the depth
    /// buffer, and draws what `draws` selects. The
    /// normal + depth target keeps what it held where nothing is drawn:
    /// read it only where the id is not 0.
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
            // Id 0: the background.
            a: 0.0,
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("raster pass"),
            // On the CPU driver each clear is a pass over the image's
            // memory, so only what is read where nothing was drawn is
            // cleared. Unshaded (hybrid mode) has no colour target. The
            // normal + depth target is never cleared: every reader (trace,
            // outline marks, accumulate, reproject) reads a texel's normal
            // and depth only where its id is not 0, that is where a
            // fragment wrote both. Raster mode's ids are mostly in the
            // colour's alpha, and its albedo is unread (the trace pass,
            // which reads it, does not run).
            color_attachments: &[
                if self.variant.shade {
                    attachment(&color, bg)
                } else {
                    None
                },
                Some(wgpu::RenderPassColorAttachment {
                    view: &normal_depth,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    },
                }),
                if self.variant.ids_in_color {
                    None
                } else {
                    attachment(&id, wgpu::Color::TRANSPARENT)
                },
                if self.variant.textures && !self.variant.shade {
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
        for call in draws.calls(scene) {
            let cull = match scene.draws[call.draw].cull {
                Cull::Back => 0,
                Cull::Front => 1,
                Cull::None => 2,
            };
            let level = call.level;
            let (pipeline, first) = if call.backward {
                (3 + cull, level.reversed_first_index())
            } else {
                (cull, level.first_index)
            };
            pass.set_pipeline(&pipelines[pipeline]);
            pass.draw_indexed(
                first..first + level.index_count,
                level.base_vertex,
                call.instances,
            );
        }
    }
}

/// What the raster pass draws of a scene for one sample.
#[derive(Debug, Clone, Default)]
pub struct RasterDraws {
    /// Raster mode draws everything; hybrid only meshes (the trace pass
    /// finds analytic shapes exactly); raytrace nothing (the renderer
    /// skips the pass there).
    pub mode: RenderMode,
    /// The level of detail of each of the scene's draws ([`draw_levels`]);
    /// missing entries draw the finest.
    pub levels: Vec<usize>,
    /// How near each of the scene's draws is to the eye ([`draw_distances`]),
    /// which orders them ([`RasterDraws::calls`]); empty: the scene's order.
    pub distances: Vec<f32>,
}

/// The most instances a draw made backward may have (one call each:
/// [`RasterDraws::calls`]).
const MAX_BACKWARD_INSTANCES: usize = 64;

/// One draw call of the raster pass: `instances` of the scene's draw
/// number `draw` at `level`.
#[derive(Debug, Clone)]
struct DrawCall {
    draw: usize,
    level: MeshLevel,
    instances: Range<u32>,
    /// The triangles in reverse order, depth-tested `LessEqual`: at equal
    /// depth the last fragment drawn stays rather than the first.
    backward: bool,
}

impl RasterDraws {
    /// The draw calls in order, each as (index into the scene's draws, its
    /// GPU instances, whether it goes backward).
    pub fn sequence(&self, scene: &SceneBuffers) -> Vec<(usize, Range<u32>, bool)> {
        self.calls(scene)
            .into_iter()
            .map(|c| (c.draw, c.instances, c.backward))
            .collect()
    }

    /// The draw calls to make, nearest draws first.
    ///
    /// Drawn front to back, a fragment behind what is already drawn fails
    /// the depth test before the fragment shader runs; the shading is most
    /// of the raster pass on the CPU driver (docs/performance-history.md). But the
    /// image must stay the one the scene's order gives, in which, at exactly
    /// equal depth (an object standing on the floor, along the line where
    /// they meet; a mesh's silhouette, where its front and back meet), the
    /// first fragment drawn stays. So the draws made so far are always a run
    /// of the scene's draws, `lo..=hi`, grown from the nearest by one
    /// neighbour at a time, the nearer of the two. Draw `hi + 1` goes
    /// forward with the `Less` test: it loses every tie to those drawn, all
    /// earlier in the scene, and keeps its own order. Draw `lo - 1` goes
    /// backward, its instances one call each from the last, each with its
    /// triangles reversed, and the `LessEqual` test: its fragments reach
    /// each pixel in exactly the reverse of the scene's order, so the last
    /// of them at the nearest depth stays, the one drawn first in the
    /// scene's order, and it wins every tie against the later draws drawn
    /// so far. Nothing lies at the far plane (the depth clear value), which
    /// the projection puts beyond the scene's bounds. A draw of more than
    /// [`MAX_BACKWARD_INSTANCES`] instances is never made backward (the run
    /// starts at or before it), nor are the draws after it.
    fn calls(&self, scene: &SceneBuffers) -> Vec<DrawCall> {
        let drawn: Vec<usize> = (0..scene.draws.len())
            .filter(|&i| scene.draws[i].drawn_in(self.mode))
            .collect();
        let key = |p: usize| self.distances.get(drawn[p]).copied().unwrap_or(0.0);
        let call = |p: usize, instances: Range<u32>, backward: bool| {
            let d = &scene.draws[drawn[p]];
            let level = self.levels.get(drawn[p]).copied().unwrap_or(0);
            DrawCall {
                draw: drawn[p],
                level: d.levels[level.min(d.levels.len() - 1)],
                instances,
                backward,
            }
        };
        let mut calls = Vec::new();
        // A draw of many instances would go backward as that many calls: the
        // run starts at or before the first such draw, so that it and every
        // draw after it go forward.
        let many = |p: &usize| scene.draws[drawn[*p]].instances.len() > MAX_BACKWARD_INSTANCES;
        let last_start = (0..drawn.len())
            .find(many)
            .unwrap_or(drawn.len().saturating_sub(1));
        // The first of the nearest (min_by keeps the first of equals).
        let Some(start) =
            (0..drawn.len().min(last_start + 1)).min_by(|&a, &b| key(a).total_cmp(&key(b)))
        else {
            return calls;
        };
        calls.push(call(
            start,
            scene.draws[drawn[start]].instances.clone(),
            false,
        ));
        let (mut lo, mut hi) = (start, start);
        while lo > 0 || hi + 1 < drawn.len() {
            if hi + 1 == drawn.len() || (lo > 0 && key(lo - 1) < key(hi + 1)) {
                lo -= 1;
                let instances = scene.draws[drawn[lo]].instances.clone();
                calls.extend(instances.rev().map(|k| call(lo, k..k + 1, true)));
            } else {
                hi += 1;
                calls.push(call(hi, scene.draws[drawn[hi]].instances.clone(), false));
            }
        }
        calls
    }
}

/// How near each of `buffers.draws` is to `eye` for one sample, to order
/// them ([`RasterDraws::calls`]): the distance to the nearest origin of its
/// instances (at the sample's shutter `time` when instances move). Planes
/// are infinitely far: a floor or a wall is behind what stands on it, but
/// its nearest point is under the eye, its origin anywhere. Draws that
/// `mode` does not draw are not measured (infinitely far too).
pub fn draw_distances(
    buffers: &SceneBuffers,
    scene: &Scene,
    mode: RenderMode,
    eye: Vec3,
    time: Option<f32>,
) -> Vec<f32> {
    buffers
        .draws
        .iter()
        .map(|d| {
            if !d.drawn_in(mode) || matches!(scene.shapes[d.shape], Shape::Plane(_)) {
                return f32::INFINITY;
            }
            d.instances
                .clone()
                .map(|gpu_index| {
                    let inst = &scene.instances[buffers.instance_order[gpu_index as usize]];
                    let m = time.map_or(inst.world_from_object, |t| inst.world_from_object_at(t));
                    m.w_axis.truncate().distance(eye)
                })
                .fold(f32::INFINITY, f32::min)
        })
        .collect()
}

/// The pipelines of one variant: the three cull modes (back, front, none)
/// with the `Less` depth test (draws made forward), then the same with
/// `LessEqual` (backward: [`RasterDraws::calls`]).
fn raster_pipelines(
    gpu: &Gpu,
    pipeline_layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    variant: RasterVariant,
) -> [wgpu::RenderPipeline; 6] {
    let textures = variant.textures;
    let mut constants = variant.shading.constants().to_vec();
    constants.extend(variant.lights.constants());
    constants.push(variant.tables.constant());
    let options = || wgpu::PipelineCompilationOptions {
        constants: &constants,
        ..Default::default()
    };
    // Untextured scenes run the entry points without texture varyings;
    // untextured hybrid mode, those that neither shade nor pass the
    // material. Textured hybrid mode keeps the textured pair, its colour
    // unwritten: a geometry-only pair measured slower there
    // (docs/performance-history.md).
    let (vs, fs) = match (textures, variant.shade) {
        (false, true) => ("vs_main", "fs_main"),
        (true, _) => ("vs_textured", "fs_textured"),
        (false, false) => ("vs_geometry", "fs_geometry"),
    };
    let target = |format, write_mask| {
        Some(wgpu::ColorTargetState {
            format,
            blend: None,
            write_mask,
        })
    };
    let all = wgpu::ColorWrites::ALL;
    let pipeline = |cull_mode, depth_compare| {
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
                    depth_compare: Some(depth_compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module,
                    entry_point: Some(fs),
                    compilation_options: options(),
                    targets: &[
                        // Unshaded fragments (hybrid mode) write no colour,
                        // and the pass has no colour target then.
                        if variant.shade {
                            target(COLOR_FORMAT, all)
                        } else {
                            None
                        },
                        target(NORMAL_DEPTH_FORMAT, all),
                        // Fragments still output the id at location 2; with
                        // no target there, the driver drops it.
                        if variant.ids_in_color {
                            None
                        } else {
                            target(ID_FORMAT, all)
                        },
                        // Only textured hybrid scenes' trace pass reads the
                        // albedo (raster mode's fs_textured writes it to no
                        // target).
                        if textures && !variant.shade {
                            target(ALBEDO_FORMAT, all)
                        } else {
                            None
                        },
                    ],
                }),
                multiview_mask: None,
                cache: None,
            })
    };
    let (forward, backward) = (
        wgpu::CompareFunction::Less,
        wgpu::CompareFunction::LessEqual,
    );
    [
        pipeline(Some(wgpu::Face::Back), forward),
        pipeline(Some(wgpu::Face::Front), forward),
        pipeline(None, forward),
        pipeline(Some(wgpu::Face::Back), backward),
        pipeline(Some(wgpu::Face::Front), backward),
        pipeline(None, backward),
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
