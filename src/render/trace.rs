//! Pass 2: ray tracing in compute. Per pixel, the same primary ray as the
//! raster pass, traced through the two-level BVH (analytic shapes only in
//! hybrid mode, composited against the raster depth; everything in raytrace
//! mode), then shadow rays and mirror or glossy reflections against the
//! whole scene. The driver variant walks the driver's acceleration
//! structures (ray queries) instead of the BVH.
//!
//! Bindings: group 0 is the scene's shared group
//! ([`crate::render::scene_buffers::SCENE_LAYOUT`]); group 1 is
//! [`PASS_LAYOUT`] (frame uniforms, the overflow counter, the G-buffers);
//! the driver variant adds the driver's structures as group 2.

use std::collections::HashMap;

use wgpu::util::DeviceExt;

use crate::accel::{shadow_cull, shape_params, PrivateSizes};
use crate::gpu::layout::{
    read_only_storage_entry, read_write_storage_entry, texture_entry, uniform_entry,
};
use crate::gpu::shader::Traversal;
use crate::gpu::twins::{
    CSG_FAST_COUNT_SHIFT, PRIMARY_TILE_WALK, PRIMARY_TILE_WORDS, SHAPE_CSG, SHAPE_MESH,
    TILE_MESH_MAY_SHOW, TILE_RECORD_READ, TILE_RECORD_SHIFT, TRACE_WORKGROUP,
};
use crate::gpu::uniform_tables::{SelectedTables, UniformTables};
use crate::gpu::{readback, shader, Gpu, GpuError};
use crate::render::driver_accel::{self, DriverAccel};
use crate::render::scene_buffers::{
    scene_layout, LightLayout, SceneBuffers, ShadingVariant, PASS_GROUP, SCENE_GROUP,
};
use crate::render::targets::Targets;
use crate::render::RenderSettings;
use crate::scene::{Light, Material, Scene, Shape};

const FLOAT: wgpu::TextureSampleType = wgpu::TextureSampleType::Float { filterable: false };

/// Group 1 of the trace pass, binding by binding as `shaders/trace.wgsl`
/// declares it.
pub const PASS_LAYOUT: [wgpu::BindGroupLayoutEntry; 13] = [
    uniform_entry(0, wgpu::ShaderStages::COMPUTE), // frame
    read_write_storage_entry(1),                   // stats
    texture_entry(2, FLOAT),                       // raster_normal_depth
    texture_entry(3, wgpu::TextureSampleType::Uint), // raster_id
    read_write_storage_entry(4),                   // out_color
    read_write_storage_entry(5),                   // out_normal_depth
    read_write_storage_entry(6),                   // out_id
    texture_entry(7, FLOAT),                       // raster_albedo
    read_only_storage_entry(8, wgpu::ShaderStages::COMPUTE), // shadow_cull
    read_only_storage_entry(9, wgpu::ShaderStages::COMPUTE), // shadow_cells
    read_only_storage_entry(10, wgpu::ShaderStages::COMPUTE), // primary_tiles
    read_only_storage_entry(11, wgpu::ShaderStages::COMPUTE), // shadow_spheres
    read_write_storage_entry(12),                  // accum
];

pub struct TracePass {
    /// Pipeline variants, each built the first time a scene needs it and
    /// kept: code a scene cannot reach (CSG, triangle meshes, shadows,
    /// reflections, glossy sampling) is compiled out, which the CPU driver
    /// runs markedly faster.
    pipelines: HashMap<Variant, wgpu::ComputePipeline>,
    variant: Variant,
    /// The pass's modules, made as variants ask for them: by traversal
    /// (packets, `lib/trace_packet.wgsl`, or each ray alone) and the
    /// private arrays' lengths.
    modules: shader::SizedModules,
    pipeline_layout: wgpu::PipelineLayout,
    scene_layout: wgpu::BindGroupLayout,
    target_layout: wgpu::BindGroupLayout,
    /// The scene's shared group and this pass's own.
    bind_groups: Option<(wgpu::BindGroup, wgpu::BindGroup)>,
    /// Counters the shader bumps: [0] = pixels that ran out of traversal steps.
    stats: wgpu::Buffer,
    /// Per 8 x 8 tile of the image, the instances its primary rays can meet
    /// (`accel::screen_tiles`; binding 10), written for each sample where
    /// the variant reads it; made at every image size, every tile walking.
    tiles: wgpu::Buffer,
    /// What `tiles` holds (empty: every tile walks, as made), so that a
    /// sample whose tiles are the last one's uploads nothing (a still
    /// camera's samples differ by their jitter, which rarely moves a
    /// rectangle across a tile's edge).
    written_tiles: Vec<u32>,
    /// The driver variant (wgpu ray queries), built the first time a scene
    /// is traced through the driver's structures; `Some` group 2 while the
    /// current scene is.
    driver: Option<DriverVariant>,
    driver_group: Option<wgpu::BindGroup>,
    /// Workgroups a dispatch looping over the tiles has (0: one per
    /// tile; [`Gpu::set_looping_groups`] when the pass was made).
    groups: u32,
}

/// The trace pass composed with `lib/trace_rq.wgsl`: its own modules, so the
/// software pipelines carry none of it. Sized per scene as the software
/// ones are: its CSG evaluator keeps the same private arrays, and a CSG
/// mesh leaf walks celray's BVH of that mesh on the same stack.
struct DriverVariant {
    modules: shader::SizedModules,
    layout: wgpu::BindGroupLayout,
    pipelines: HashMap<Variant, wgpu::ComputePipeline>,
}

/// Which optional code a scene and its settings need in the trace kernel.
/// Each flag is false only where the code it guards could change no pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Variant {
    csg: bool,
    /// `CSG_FAST_LEAVES` (lib/csg.wgsl): the most leaves of the scene's CSG
    /// programs that are evaluated by their truth table (0: none).
    csg_fast_leaves: u32,
    /// `CSG_INTERPRETER`: some CSG program runs on interval lists.
    csg_interpreter: bool,
    meshes: bool,
    /// `SHADOW_LIGHTS`: bit i for light i (< 32) that casts shadows
    /// (`SHADOWS_ENABLED` where some bit or `shadow_lights_from_32` is set).
    shadow_lights: u32,
    /// `SHADOW_LIGHTS_FROM_32`: some light from index 32 on casts shadows.
    /// The kernel also checks each light's own flag, so a variant that tests
    /// more lights than cast shadows draws the same picture (see
    /// [`TracePass::variant_for_edit`]).
    shadow_lights_from_32: bool,
    /// `SHADOW_LISTS`: shadow rays may be answered by their receiver's
    /// occluder list (`accel::shadow_cull`): the scene has lists
    /// (`SceneBuffers::shadow_lists`), some instance is an analytic shape
    /// (a list's receiver and entries are), and exactly one light casts
    /// shadows, a directional one of the first `MAX_CULL_LIGHTS`. With
    /// more, `shade_hit` casts the shadow rays in a loop, and there the list
    /// code alone slowed the default scene's trace pass 1.34x on lavapipe
    /// (docs/performance-history.md, twentieth session).
    shadow_lists: bool,
    /// `PRIMARY_TILES`: primary rays test their screen tile's instances
    /// (`SceneBuffers::primary_tiles`).
    primary_tiles: bool,
    reflections: bool,
    glossy: bool,
    textures: bool,
    /// `ANALYTIC_KINDS` (lib/intersect.wgsl): bit 1 << kind for each
    /// analytic shape kind at the top level or in a CSG leaf.
    analytic_kinds: u32,
    /// What the materials and lights need of the shading code.
    shading: ShadingVariant,
    /// The lights' count and kinds, when fixed: the shading loop over the
    /// lights unrolls.
    lights: LightLayout,
    /// The tables read from their uniform copies.
    tables: UniformTables,
    /// The tables read by selection.
    selected: SelectedTables,
    /// `FLAT_TOP_LEVEL`: the instance count where rays test every
    /// instance instead of walking the top level
    /// (`SceneBuffers::flat_top_level`), else 0.
    flat_top_level: u32,
    /// The BVH walked as packets of 8 (`SceneBuffers::packet_trace`;
    /// `lib/trace_packet.wgsl`), else each ray on its own.
    packet: bool,
    /// The lengths of the private arrays (`SceneAccel::sizes`: the
    /// traversal stack, the CSG evaluator's). Not override constants,
    /// since WGSL sizes private arrays only by constants: each set of
    /// lengths has a module of its own.
    sizes: PrivateSizes,
}

impl Variant {
    pub fn of(scene: &Scene, buffers: &SceneBuffers, settings: &RenderSettings) -> Variant {
        // Only what some instance shows counts: a definition no instance
        // uses could change no pixel.
        let reflective: Vec<&Material> = scene
            .used_materials()
            .filter(|m| m.reflectivity > 0.0)
            .collect();
        let kinds = used_kinds(scene);
        let reflections = settings.max_bounces > 0 && !reflective.is_empty();
        let casts: Vec<bool> = scene.lights.iter().map(Light::casts_shadows).collect();
        let mask_lights = u32::BITS as usize;
        let (csg_fast_leaves, csg_interpreter) = csg_programs(scene, buffers);
        Variant {
            csg: kinds & 1 << SHAPE_CSG != 0,
            csg_fast_leaves,
            csg_interpreter,
            meshes: kinds & 1 << SHAPE_MESH != 0,
            shadow_lights: casts
                .iter()
                .take(mask_lights)
                .enumerate()
                .filter(|(_, &c)| c)
                .fold(0, |bits, (i, _)| bits | 1 << i),
            shadow_lights_from_32: casts.iter().skip(mask_lights).any(|&c| c),
            shadow_lists: shadow_lists(scene, buffers),
            primary_tiles: buffers.primary_tiles,
            reflections,
            glossy: reflections && reflective.iter().any(|m| m.roughness > 0.0),
            textures: buffers.uses_textures,
            analytic_kinds: kinds & ((1 << SHAPE_MESH) - 1),
            shading: ShadingVariant::of(scene),
            lights: LightLayout::of(&scene.lights),
            tables: buffers.tables,
            selected: buffers.selected,
            flat_top_level: buffers.flat_top_level,
            packet: buffers.packet_trace,
            sizes: buffers.accel.sizes,
        }
    }

    /// Whether the kernel may answer shadow rays by occluder lists.
    pub fn shadow_lists(self) -> bool {
        self.shadow_lists
    }

    /// Whether primary rays test their screen tile's instances.
    pub fn primary_tiles(self) -> bool {
        self.primary_tiles
    }

    /// The instance count where rays test every instance instead of
    /// walking the top level, else 0.
    pub fn flat_top_level(self) -> u32 {
        self.flat_top_level
    }

    /// The override constants that select this variant in trace.wgsl.
    fn constants(self) -> Vec<(&'static str, f64)> {
        let flag = |b: bool| f64::from(u8::from(b));
        let mut constants = vec![
            ("CSG_ENABLED", flag(self.csg)),
            ("CSG_FAST_LEAVES", f64::from(self.csg_fast_leaves)),
            ("CSG_INTERPRETER", flag(self.csg_interpreter)),
            ("MESHES_ENABLED", flag(self.meshes)),
            (
                "SHADOWS_ENABLED",
                flag(self.shadow_lights != 0 || self.shadow_lights_from_32),
            ),
            ("SHADOW_LIGHTS", f64::from(self.shadow_lights)),
            ("SHADOW_LIGHTS_FROM_32", flag(self.shadow_lights_from_32)),
            ("SHADOW_LISTS", flag(self.shadow_lists)),
            ("PRIMARY_TILES", flag(self.primary_tiles)),
            ("REFLECTIONS_ENABLED", flag(self.reflections)),
            ("GLOSSY_ENABLED", flag(self.glossy)),
            ("TEXTURES_ENABLED", flag(self.textures)),
            ("ANALYTIC_KINDS", f64::from(self.analytic_kinds)),
            ("FLAT_TOP_LEVEL", f64::from(self.flat_top_level)),
        ];
        constants.extend(self.shading.constants());
        constants.extend(self.lights.constants());
        constants.push(self.tables.constant());
        constants.extend(self.selected.constants());
        constants
    }
}

/// Whether a shadow ray may be answered by an occluder list (see
/// [`Variant::shadow_lists`]).
fn shadow_lists(scene: &Scene, buffers: &SceneBuffers) -> bool {
    buffers.shadow_lists && shadow_cull::lists_read(&buffers.accel, &scene.lights)
}

/// Of the scene's CSG programs: the most leaves of those evaluated by their
/// truth table (`GpuShape::csg_fast`), and whether some other runs on
/// interval lists.
fn csg_programs(scene: &Scene, buffers: &SceneBuffers) -> (u32, bool) {
    let csg = scene.used_shapes().map(|(id, _)| &buffers.accel.shapes[id]);
    csg.filter(|s| s.kind == SHAPE_CSG)
        .fold((0, false), |(most, lists), s| {
            let leaves = s.csg_fast >> CSG_FAST_COUNT_SHIFT;
            (most.max(leaves), lists || s.csg_fast == 0)
        })
}

/// The shape kinds (bit 1 << kind) of the shapes instances show and of
/// their CSG leaves: analytic kinds, `SHAPE_MESH` (a mesh, or a closed
/// mesh in a tree) and `SHAPE_CSG`.
fn used_kinds(scene: &Scene) -> u32 {
    let kind = |shape: &Shape| 1 << shape_params(shape).0;
    scene.used_shapes().fold(0, |bits, (_, shape)| {
        let leaves = match shape {
            Shape::Csg(csg) => csg.root.leaves().iter().fold(0, |b, l| b | kind(&l.shape)),
            _ => 0,
        };
        bits | kind(shape) | leaves
    })
}

/// The trace workgroups (8 x 8 pixel tiles) over a `width` x `height` image.
fn tile_count(width: u32, height: u32) -> u64 {
    u64::from(width.div_ceil(TRACE_WORKGROUP)) * u64::from(height.div_ceil(TRACE_WORKGROUP))
}

/// The words of the tile buffer of a `width` x `height` image: per tile a
/// record of `PRIMARY_TILE_WORDS`, then per tile its flags: whether a
/// rasterized mesh may show there, and whether the pass accumulates its
/// pixels (`Renderer::primary_tiles`).
fn tile_words(width: u32, height: u32) -> usize {
    tile_count(width, height) as usize * (PRIMARY_TILE_WORDS as usize + 1)
}

/// A tile buffer for the image whose every tile walks the BVH and may
/// show a mesh, and whose colour the accumulate pass adds: what a variant
/// with `PRIMARY_TILES` reads before the first tiles are written.
fn walking_tiles(gpu: &Gpu, width: u32, height: u32) -> wgpu::Buffer {
    let records = tile_count(width, height) as usize * PRIMARY_TILE_WORDS as usize;
    let mut words = vec![PRIMARY_TILE_WALK; records];
    words.resize(
        tile_words(width, height),
        TILE_MESH_MAY_SHOW | TILE_RECORD_READ << TILE_RECORD_SHIFT,
    );
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("primary ray tiles"),
            contents: bytemuck::cast_slice(&words),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
        })
}

/// The trace pipeline with only the code `variant` needs.
fn trace_pipeline(
    gpu: &Gpu,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    variant: Variant,
) -> wgpu::ComputePipeline {
    gpu.device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("trace pipeline"),
            layout: Some(layout),
            module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &[variant.constants(), vec![gpu.edge_tolerance_constant()]].concat(),
                ..Default::default()
            },
            cache: None,
        })
}

impl TracePass {
    pub fn new(gpu: &Gpu) -> Result<TracePass, GpuError> {
        gpu.scoped(|| {
            let scene_layout = scene_layout(gpu);
            let target_layout =
                gpu.device
                    .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                        label: Some("trace pass layout"),
                        entries: &PASS_LAYOUT,
                    });
            let layout = gpu
                .device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("trace pipeline layout"),
                    bind_group_layouts: &[Some(&scene_layout), Some(&target_layout)],
                    immediate_size: 0,
                });
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
                pipelines: HashMap::new(),
                variant: Variant::default(),
                modules: shader::SizedModules::new("trace.wgsl"),
                pipeline_layout: layout,
                scene_layout,
                target_layout,
                bind_groups: None,
                stats,
                tiles: walking_tiles(gpu, 1, 1),
                written_tiles: Vec::new(),
                driver: None,
                driver_group: None,
                groups: gpu.looping_groups(),
            }
        })
    }

    /// The variant to use when a live edit of materials or lights asks for
    /// `want`: `want`, testing also the lights the current variant tests for
    /// shadows. A light that stops casting shadows then needs no new
    /// pipeline (building one takes seconds on the CPU driver), and one that
    /// starts needs at most one per light.
    pub fn variant_for_edit(&self, want: Variant) -> Variant {
        let now = self.variant;
        Variant {
            shadow_lights: want.shadow_lights | now.shadow_lights,
            shadow_lights_from_32: want.shadow_lights_from_32 || now.shadow_lights_from_32,
            shadow_lists: (want.shadow_lists || now.shadow_lists)
                && (want.shadow_lights | now.shadow_lights).count_ones() == 1
                && !(want.shadow_lights_from_32 || now.shadow_lights_from_32),
            ..want
        }
    }

    /// The variant the pass traces with now.
    pub fn variant(&self) -> Variant {
        self.variant
    }

    /// Whether the pass has built `variant`'s pipeline on the current path
    /// (driver or software).
    pub fn has_variant(&self, variant: Variant) -> bool {
        self.path_pipelines().contains_key(&variant)
    }

    /// The pipelines built so far on the current path (driver or software).
    fn path_pipelines(&self) -> &HashMap<Variant, wgpu::ComputePipeline> {
        match (&self.driver_group, &self.driver) {
            (Some(_), Some(v)) => &v.pipelines,
            _ => &self.pipelines,
        }
    }

    /// Uses the pipeline for `variant` on the current path (driver or
    /// software), building it now if this pass has not yet.
    pub fn select_variant(&mut self, gpu: &Gpu, variant: Variant) -> Result<(), GpuError> {
        self.variant = variant;
        if self.driver_group.is_some() {
            if let Some(v) = self.driver.as_mut() {
                if !v.pipelines.contains_key(&variant) {
                    let layouts = [&self.scene_layout, &self.target_layout];
                    let module = v.modules.get(gpu, Traversal::Driver, variant.sizes)?;
                    let pipeline = gpu.scoped(|| {
                        driver_accel::pipeline(
                            gpu,
                            "trace pipeline (driver ray queries)",
                            module,
                            &layouts,
                            &v.layout,
                            // Primary rays go to the driver's traversal:
                            // tiles would test meshes with celray's own
                            // triangle test instead.
                            &Variant {
                                primary_tiles: false,
                                ..variant
                            }
                            .constants(),
                        )
                    })?;
                    v.pipelines.insert(variant, pipeline);
                }
            }
        } else if !self.pipelines.contains_key(&variant) {
            if variant.packet && !gpu.packet_walk() {
                return Err(GpuError::Unsupported(format!(
                    "a packet-walk trace variant on a device without it ({})",
                    gpu.summary
                )));
            }
            let traversal = if variant.packet {
                Traversal::Packet
            } else {
                Traversal::Software
            };
            let module = self.modules.get(gpu, traversal, variant.sizes)?;
            let pipeline = trace_pipeline(gpu, &self.pipeline_layout, module, variant);
            self.pipelines.insert(variant, pipeline);
        }
        Ok(())
    }

    /// Binds `scene` and `targets`; with `driver`, the pass traces through
    /// the driver's structures (the driver variant), else celray's BVH.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        frame: &wgpu::Buffer,
        scene: &SceneBuffers,
        targets: &Targets,
        driver: Option<&DriverAccel>,
        variant: Variant,
    ) -> Result<(), GpuError> {
        self.driver_group = None;
        if let Some(accel) = driver {
            if self.driver.is_none() {
                let layout = gpu.scoped(|| driver_accel::bind_group_layout(gpu))?;
                self.driver = Some(DriverVariant {
                    modules: shader::SizedModules::new("trace.wgsl"),
                    layout,
                    pipelines: HashMap::new(),
                });
            }
            if let Some(v) = self.driver.as_ref() {
                self.driver_group = Some(accel.bind_group(gpu, &v.layout));
            }
        }
        if let Err(e) = self.select_variant(gpu, variant) {
            self.driver_group = None;
            return Err(e);
        }
        let [normal_depth, id, albedo] = [
            &targets.raster.normal_depth,
            &targets.raster.id,
            &targets.raster_albedo,
        ]
        .map(|t| t.create_view(&Default::default()));
        let tiles_bytes = tile_words(targets.width, targets.height) as u64 * 4;
        if self.tiles.size() != tiles_bytes {
            self.tiles = walking_tiles(gpu, targets.width, targets.height);
            self.written_tiles.clear();
        }
        let out = &targets.traced_output;
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 0,
                resource: frame.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: self.stats.as_entire_binding(),
            },
        ];
        for (binding, view) in [(2, &normal_depth), (3, &id), (7, &albedo)] {
            entries.push(wgpu::BindGroupEntry {
                binding,
                resource: wgpu::BindingResource::TextureView(view),
            });
        }
        for (binding, buffer) in [(4, &out.color), (5, &out.normal_depth), (6, &out.id)] {
            entries.push(wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            });
        }
        entries.extend([
            wgpu::BindGroupEntry {
                binding: 8,
                resource: scene.shadow_cull.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 9,
                resource: scene.shadow_cells.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 10,
                resource: self.tiles.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 11,
                resource: scene.shadow_cells.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 12,
                resource: targets.accum.as_entire_binding(),
            },
        ]);
        let target_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("trace pass bind group"),
            layout: &self.target_layout,
            entries: &entries,
        });
        self.bind_groups = Some((scene.bind_group.clone(), target_group));
        Ok(())
    }

    /// Whether the kernel reads primary tiles: the variant has them and
    /// the pass walks celray's BVH (the driver variant is built without).
    pub fn reads_tiles(&self) -> bool {
        self.variant.primary_tiles && !self.uses_driver()
    }

    /// The primary tiles the kernel last read (for tests).
    pub fn read_tiles(&self, gpu: &Gpu) -> Result<Vec<u32>, GpuError> {
        let bytes = readback::copy_and_read(
            gpu,
            &self.tiles,
            self.tiles.size(),
            "primary tiles readback",
        )?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }

    /// Writes the primary rays' tiles of the next sample
    /// (`accel::screen_tiles::primary_tiles` over the image the pass was
    /// prepared for), where they differ from what the buffer holds.
    pub fn write_tiles(&mut self, gpu: &Gpu, tiles: Vec<u32>) {
        crate::gpu::write_if_changed(gpu, &self.tiles, &mut self.written_tiles, tiles);
    }

    /// Whether the pass traces through the driver's structures.
    pub fn uses_driver(&self) -> bool {
        self.driver_group.is_some()
    }

    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let Some((scene_group, target_group)) = &self.bind_groups else {
            return;
        };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("trace pass"),
            timestamp_writes,
        });
        let Some(pipeline) = self.path_pipelines().get(&self.variant) else {
            return;
        };
        pass.set_pipeline(pipeline);
        pass.set_bind_group(SCENE_GROUP, scene_group, &[]);
        pass.set_bind_group(PASS_GROUP, target_group, &[]);
        if let Some(group) = &self.driver_group {
            pass.set_bind_group(driver_accel::DRIVER_GROUP, group, &[]);
        }
        let tiles = (
            targets.width.div_ceil(TRACE_WORKGROUP),
            targets.height.div_ceil(TRACE_WORKGROUP),
        );
        // Fewer workgroups than tiles loop over them (trace.wgsl's main).
        if self.groups > 0 && self.groups < tiles.0 * tiles.1 {
            pass.dispatch_workgroups(self.groups, 1, 1);
        } else {
            pass.dispatch_workgroups(tiles.0, tiles.1, 1);
        }
    }

    /// Pixels (summed over samples) whose traversal ran out of its step
    /// budget since this pass was created: 0 unless the scene is too deep.
    pub fn overflow_pixels(&self, gpu: &Gpu) -> Result<u32, GpuError> {
        let bytes = readback::copy_and_read(gpu, &self.stats, 16, "trace stats readback")?;
        Ok(bytemuck::cast_slice::<u8, u32>(&bytes)[0])
    }
}
