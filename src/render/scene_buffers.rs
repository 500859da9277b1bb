//! The scene on the GPU: one vertex and index buffer holding every base
//! shape's triangles, per-instance matrices sorted by shape (so each shape is
//! one instanced draw), materials and lights, the ray tracer's BVHs, shapes
//! and CSG programs, and the base-colour maps.
//!
//! Also the scene's bind group, group [`SCENE_GROUP`] of every pass that
//! reads the scene (raster, trace, ray batch, accumulate): its layout is
//! [`SCENE_LAYOUT`], the twin of `shaders/lib/scene_bindings.wgsl`, and
//! [`SceneBuffers::bind_group`] is built once per upload and shared by the
//! passes; each pass's own resources are in group [`PASS_GROUP`].

use glam::Mat4;
use wgpu::util::DeviceExt;

use crate::accel::{shadow_cull, SceneAccel};
use crate::gpu::layout::{
    buffer_entries, map_array_entry, read_only_storage_entry, sampler_entry, uniform_entry,
};
use crate::gpu::twins::{
    GpuInstance, GpuLight, GpuMaterial, Vertex, LIGHTS_DYNAMIC, MAX_TOON_BANDS, NO_TEXTURE,
    SHADING_BLINN_PHONG, SHADING_TOON,
};
use crate::gpu::uniform_tables::{SelectedTables, Table, UniformTables, UNIFORM_TABLE_BYTES};
use crate::gpu::{Gpu, GpuError};
use crate::render::settings::RenderMode;
use crate::render::textures::{scene_uses_textures, SceneTextures};
use crate::scene::{
    sphere_inset, tessellate, tessellate_sphere, Light, Material, Mesh, Pattern, Scene,
    ShadingModel, Shape, TextureFilter, SPHERE_LEVELS,
};

/// The scene's group in every pass that reads it.
pub const SCENE_GROUP: u32 = 0;
/// A pass's own resources (frame uniforms, targets, its outputs).
pub const PASS_GROUP: u32 = 1;

/// The stages that see the scene: the raster pass's vertex and fragment
/// shaders and the compute passes.
const SCENE_VISIBILITY: wgpu::ShaderStages =
    wgpu::ShaderStages::VERTEX_FRAGMENT.union(wgpu::ShaderStages::COMPUTE);

/// The scene's bind group layout, binding by binding as
/// `shaders/lib/scene_bindings.wgsl` declares it.
pub const SCENE_LAYOUT: [wgpu::BindGroupLayoutEntry; 21] = [
    read_only_storage_entry(0, SCENE_VISIBILITY), // instances
    read_only_storage_entry(1, SCENE_VISIBILITY), // materials
    read_only_storage_entry(2, SCENE_VISIBILITY), // lights
    read_only_storage_entry(3, SCENE_VISIBILITY), // shapes
    read_only_storage_entry(4, SCENE_VISIBILITY), // nodes
    read_only_storage_entry(5, SCENE_VISIBILITY), // triangles
    read_only_storage_entry(6, SCENE_VISIBILITY), // tlas_items
    read_only_storage_entry(7, SCENE_VISIBILITY), // csg_ops
    read_only_storage_entry(8, SCENE_VISIBILITY), // csg_leaves
    read_only_storage_entry(9, SCENE_VISIBILITY), // triangle_maps
    map_array_entry(10, SCENE_VISIBILITY),        // base_color_maps
    sampler_entry(11, SCENE_VISIBILITY),          // map_linear
    sampler_entry(12, SCENE_VISIBILITY),          // map_nearest
    // The uniform copies (gpu::uniform_tables).
    uniform_entry(Table::Nodes.binding(), SCENE_VISIBILITY), // nodes_u
    uniform_entry(Table::Instances.binding(), SCENE_VISIBILITY), // instances_u
    uniform_entry(Table::Shapes.binding(), SCENE_VISIBILITY), // shapes_u
    uniform_entry(Table::Materials.binding(), SCENE_VISIBILITY), // materials_u
    uniform_entry(Table::CsgOps.binding(), SCENE_VISIBILITY), // csg_ops_u
    uniform_entry(Table::CsgLeaves.binding(), SCENE_VISIBILITY), // csg_leaves_u
    // The packet walk's word views of nodes and triangles (the same
    // buffers; shaders/lib/trace_packet.wgsl).
    read_only_storage_entry(19, wgpu::ShaderStages::COMPUTE), // node_words
    read_only_storage_entry(20, wgpu::ShaderStages::COMPUTE), // triangle_words
];

/// The scene's bind group layout object. wgpu pools layouts by their
/// entries, so every pass's pipeline and every scene's bind group get the
/// one same layout from here.
pub fn scene_layout(gpu: &Gpu) -> wgpu::BindGroupLayout {
    gpu.device
        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scene bind group layout"),
            entries: &SCENE_LAYOUT,
        })
}

/// Which triangles a draw may skip. Closed analytic shapes are drawn with
/// back faces culled (front faces when the instance mirrors, which flips the
/// winding); planes and meshes from files (maybe open) are two-sided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Cull {
    Back,
    Front,
    None,
}

/// One instanced draw: a base shape's triangles (at each of its levels of
/// detail) and its instances.
#[derive(Debug, Clone)]
pub struct Draw {
    pub shape: usize,
    /// A triangle mesh from a file (hybrid mode rasterizes only these).
    pub is_mesh: bool,
    pub cull: Cull,
    /// The shape's triangles, finest first: one level, or a sphere's
    /// [`SPHERE_LEVELS`] (the raster pass picks one per frame,
    /// `render::raster::draw_levels`).
    pub levels: Vec<MeshLevel>,
    pub instances: std::ops::Range<u32>,
}

/// One tessellation of a base shape in the scene's vertex and index
/// buffers.
#[derive(Debug, Clone, Copy)]
pub struct MeshLevel {
    pub first_index: u32,
    pub index_count: u32,
    pub base_vertex: i32,
    /// How far inside the true surface the triangles reach, in object
    /// units ([`sphere_inset`]); 0 where they are the surface.
    pub inset: f32,
}

impl MeshLevel {
    /// Where the same triangles start in reverse order (each keeping its
    /// winding): uploaded right after the level's own. The raster pass
    /// draws a shape backwards where it must win the ties the forward order
    /// lost (`render::raster::RasterDraws::calls`).
    pub fn reversed_first_index(&self) -> u32 {
        self.first_index + self.index_count
    }
}

impl Draw {
    /// Whether the raster pass draws this in `mode`: everything in raster
    /// mode, the meshes in hybrid mode (the trace pass finds analytic
    /// shapes exactly), nothing in raytrace mode.
    pub fn drawn_in(&self, mode: RenderMode) -> bool {
        match mode {
            RenderMode::Raster => true,
            RenderMode::Hybrid => self.is_mesh,
            RenderMode::Raytrace => false,
        }
    }
}

pub struct SceneBuffers {
    pub vertices: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    pub instances: wgpu::Buffer,
    pub materials: wgpu::Buffer,
    pub lights: wgpu::Buffer,
    pub light_count: u32,
    pub draws: Vec<Draw>,
    /// `instance_order[i]` is the scene instance drawn as GPU instance i.
    pub instance_order: Vec<usize>,
    pub triangle_count: u64,
    /// World bounds of every instance, computed once at upload.
    pub world_bounds: (glam::Vec3, glam::Vec3),
    /// Whether any instance moves over the shutter (matrices then change
    /// per sample).
    pub has_motion: bool,
    /// The ray tracer's view of the scene, kept on the CPU: the trace
    /// variant's key, the driver's structures, [`crate::render::Renderer::pick`]
    /// (click-to-focus) and the tests read it.
    pub accel: SceneAccel,
    pub shapes: wgpu::Buffer,
    pub nodes: wgpu::Buffer,
    pub triangles: wgpu::Buffer,
    pub tlas_items: wgpu::Buffer,
    /// CSG programs and leaves (one dummy element when there are none).
    pub csg_ops: wgpu::Buffer,
    pub csg_leaves: wgpu::Buffer,
    /// Per trace triangle: its mesh's own map layer, or NO_TEXTURE.
    pub triangle_maps: wgpu::Buffer,
    /// Base-colour images (a 1x1 white layer when there are none).
    pub textures: SceneTextures,
    /// Which shadow rays can meet anything, per light
    /// ([`crate::accel::shadow_cull`]; the trace pass's bindings 8 and 9),
    /// rewritten when lights are edited.
    pub shadow_cull: wgpu::Buffer,
    pub shadow_cells: wgpu::Buffer,
    /// The lone sun's culled regions (`shadow_cull::ShadowCull::sun`),
    /// for the CPU's proofs over the trace pass's tiles
    /// (`TILE_UNSHADOWED`); the cull data itself lives on the GPU only.
    pub sun: Option<shadow_cull::CulledRegions>,
    /// Whether `shadow_cells` has room for occluder lists
    /// (`Gpu::shadow_lists` at upload), which light edits keep; they are
    /// filled only where the trace kernel reads them
    /// (`shadow_cull::lists_read`).
    pub shadow_lists: bool,
    /// Which tables the passes read from their uniform copies
    /// ([`crate::gpu::uniform_tables`]): part of every pipeline's key.
    pub tables: UniformTables,
    /// Which tables the trace pass reads by selection
    /// ([`SelectedTables`], where [`Gpu::select_tables`]).
    pub selected: SelectedTables,
    /// Whether the trace pass walks this scene's BVH as packets
    /// (`shaders/lib/trace_packet.wgsl`): where the device can
    /// ([`Gpu::packet_walk`]) and the top-level tree's nodes are read from
    /// storage (no uniform copy holds them: over about 1,000 instances).
    /// There the packet walk measured faster; where a copy holds them, each
    /// ray walking alone did (docs/performance-history.md, nineteenth
    /// session).
    pub packet_trace: bool,
    /// Whether primary rays test their screen tile's instances
    /// (`accel::screen_tiles`, made for each sample's camera) instead of
    /// walking the BVH: where [`Gpu::primary_tiles`] and the scene has at
    /// most `MAX_TILED_INSTANCES` instances.
    pub primary_tiles: bool,
    /// The scene's instance count where rays that walk the top level test
    /// every instance in turn instead (override `FLAT_TOP_LEVEL`,
    /// lib/traverse.wgsl): where [`Gpu::flat_top_level`], the trace pass
    /// walks each ray alone (not [`SceneBuffers::packet_trace`]) and the
    /// scene has 1 to [`FLAT_TOP_LEVEL_MAX`] instances; else 0 (walk).
    pub flat_top_level: u32,
    /// The uniform copies, in [`Table::ALL`]'s order; a table that does not
    /// fit binds a zero-filled buffer of the same size that nothing reads.
    uniform_copies: Vec<wgpu::Buffer>,
    /// Whether any material has an image or a pattern, or any mesh its
    /// own map: passes compile
    /// their texture code in only then (override `TEXTURES_ENABLED`).
    pub uses_textures: bool,
    /// Group [`SCENE_GROUP`] of every pass that reads the scene
    /// ([`SCENE_LAYOUT`]), built once at upload.
    pub bind_group: wgpu::BindGroup,
}

/// What the shading code must handle for a scene's materials and lights:
/// the override constants of lib/shading.wgsl, which the raster and trace
/// pipelines are keyed by (code no material or light needs is left out).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ShadingVariant {
    /// `TOON_THRESHOLD_VECS`: the vec4s of toon thresholds (four to a
    /// vec4, as [`material_to_gpu`] packs them) the materials fill, 1 to
    /// 4; the slots beyond hold 2.0 and add nothing to a band.
    toon_threshold_vecs: u8,
    /// `SHADING_MODELS`: bit 0 Blinn-Phong, bit 1 toon.
    models: u8,
    /// `LIGHT_KINDS`: bit 0 directional, bit 1 point.
    lights: u8,
}

impl Default for ShadingVariant {
    /// Everything (what the shaders assume when nothing is set).
    fn default() -> Self {
        ShadingVariant {
            toon_threshold_vecs: 4,
            models: 3,
            lights: 3,
        }
    }
}

impl ShadingVariant {
    /// The shading code the materials some surface of `scene` shows and
    /// its lights need.
    pub fn of(scene: &Scene) -> ShadingVariant {
        let materials: Vec<&Material> = scene.used_materials().collect();
        let lights = &scene.lights;
        let most = materials
            .iter()
            .filter_map(|m| match &m.model {
                ShadingModel::Toon(toon) => Some(toon.thresholds.len()),
                ShadingModel::BlinnPhong => None,
            })
            .max()
            .unwrap_or(0)
            .min(MAX_TOON_BANDS as usize - 1);
        let models = materials.iter().fold(0, |bits, m| {
            bits | match m.model {
                ShadingModel::BlinnPhong => 1,
                ShadingModel::Toon(_) => 2,
            }
        });
        let lights = lights.iter().fold(0, |bits, l| {
            bits | match l {
                Light::Directional { .. } => 1,
                Light::Point { .. } => 2,
            }
        });
        ShadingVariant {
            toon_threshold_vecs: u8::try_from(most.div_ceil(4).clamp(1, 4)).expect("1 to 4"),
            // No material or no light at all: nothing to leave out.
            models: if models == 0 { 3 } else { models },
            lights: if lights == 0 { 3 } else { lights },
        }
    }

    /// The override constants that select this variant in lib/shading.wgsl.
    pub fn constants(self) -> [(&'static str, f64); 3] {
        [
            ("TOON_THRESHOLD_VECS", f64::from(self.toon_threshold_vecs)),
            ("SHADING_MODELS", f64::from(self.models)),
            ("LIGHT_KINDS", f64::from(self.lights)),
        ]
    }
}

/// Scenes with at most this many instances test each in turn, where a ray
/// would walk the top-level tree (override `FLAT_TOP_LEVEL`,
/// lib/traverse.wgsl). On lavapipe every lane then tests the same
/// instance at once; trace pass against the walk, paired (hybrid): 3
/// instances (csg_textbook) 0.967, 5 (mirrors) 0.953, 6
/// (anchor_dof_motion) 0.935, 8 spheres 0.910, 12 0.989, 16 1.035, 32
/// 1.291 (docs/performance-history.md, fortieth session).
pub const FLAT_TOP_LEVEL_MAX: usize = 8;

/// [`SceneBuffers::flat_top_level`] for a scene of `instances` instances.
fn flat_top_level(gpu: &Gpu, instances: usize, packet_trace: bool) -> u32 {
    let flat =
        gpu.flat_top_level() && !packet_trace && (1..=FLAT_TOP_LEVEL_MAX).contains(&instances);
    if flat {
        instances as u32
    } else {
        0
    }
}

/// Scenes with at most this many lights get raster and trace pipelines
/// with the light count and each light's kind fixed ([`LightLayout`]).
pub const MAX_FIXED_LIGHTS: u32 = 8;

/// The light count and each light's kind, fixed in the raster and trace
/// pipelines of scenes with at most [`MAX_FIXED_LIGHTS`] lights (override
/// constants `LIGHT_COUNT` and `POINT_LIGHTS` of lib/shading.wgsl): the
/// light loops unroll and each light runs only its kind's code. On
/// lavapipe this takes about a third off the default scene's raster pass
/// and about a tenth off its trace pass (docs/performance-history.md). Adding,
/// removing or changing the kind of a light builds new pipelines (the app
/// compiles them ahead, render::warmup).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct LightLayout {
    /// `LIGHT_COUNT`: the number of lights, or [`LIGHTS_DYNAMIC`].
    count: u32,
    /// `POINT_LIGHTS`: bit i set when light i is a point light.
    point_lights: u32,
}

impl Default for LightLayout {
    /// Not fixed: loops run to `frame.light_count` and test each kind.
    fn default() -> Self {
        LightLayout {
            count: LIGHTS_DYNAMIC,
            point_lights: 0,
        }
    }
}

impl LightLayout {
    pub fn of(lights: &[Light]) -> LightLayout {
        if lights.len() > MAX_FIXED_LIGHTS as usize {
            return LightLayout::default();
        }
        let point_lights = lights.iter().enumerate().fold(0, |bits, (i, l)| match l {
            Light::Point { .. } => bits | 1 << i,
            Light::Directional { .. } => bits,
        });
        LightLayout {
            count: lights.len() as u32,
            point_lights,
        }
    }

    /// The override constants that fix this layout in lib/shading.wgsl.
    pub fn constants(self) -> [(&'static str, f64); 2] {
        [
            ("LIGHT_COUNT", f64::from(self.count)),
            ("POINT_LIGHTS", f64::from(self.point_lights)),
        ]
    }
}

/// The GPU form of a material; `textures` gives its image's array layer.
pub fn material_to_gpu(m: &Material, textures: &SceneTextures) -> GpuMaterial {
    let mut g = GpuMaterial {
        base_color: m.base_color.to_array(),
        shininess: m.shininess,
        specular_color: m.specular_color.to_array(),
        highlight_cos: 1.0,
        outline_color: m.outline_color.to_array(),
        outline_width_px: m.outline_width_px,
        rim_color: [0.0; 3],
        rim_threshold: 2.0,
        model: SHADING_BLINN_PHONG,
        band_count: 1,
        reflectivity: m.reflectivity,
        roughness: m.roughness,
        // Unused slots above any N.L (see toon_band in shaders/lib/shading.wgsl).
        thresholds: [[2.0; 4]; 4],
        checker_a: [0.0; 3],
        checker_size: 0.0,
        checker_b: [0.0; 3],
        texture_layer: m
            .base_color_texture
            .as_ref()
            .and_then(|t| textures.layer_of(&t.texture))
            .unwrap_or(NO_TEXTURE),
        uv_scale: m.uv_scale.to_array(),
        texture_nearest: u32::from(matches!(
            m.base_color_texture.as_ref().map(|t| t.filter),
            Some(TextureFilter::Nearest)
        )),
        _pad: 0,
    };
    if let Some(Pattern::Checker { a, b, size }) = m.base_color_pattern {
        g.checker_a = a.to_array();
        g.checker_b = b.to_array();
        g.checker_size = size;
    }
    if let ShadingModel::Toon(toon) = &m.model {
        g.model = SHADING_TOON;
        g.band_count = toon.bands().min(MAX_TOON_BANDS);
        g.highlight_cos = highlight_cos(toon.specular_threshold, m.shininess);
        for (i, t) in toon
            .thresholds
            .iter()
            .take(MAX_TOON_BANDS as usize - 1)
            .enumerate()
        {
            g.thresholds[i / 4][i % 4] = *t;
        }
        if let Some(rim) = &toon.rim {
            g.rim_color = rim.color.to_array();
            g.rim_threshold = rim.threshold;
        }
    }
    g
}

/// The toon highlight's test (N.H)^s > t as N.H > c (s > 0 and t in
/// [0, 1], as validated; pow is increasing on N.H >= 0): c is the root
/// t^(1/s), taken in f64 and rounded down to an f32, so that for every
/// f32 N.H, N.H > c exactly where N.H > t^(1/s) (no f32 lies between the
/// root and the next f32 above c). t = 0 lights every N.H > 0.
pub fn highlight_cos(threshold: f32, shininess: f32) -> f32 {
    let root = f64::from(threshold).powf(1.0 / f64::from(shininess));
    let c = root as f32;
    if f64::from(c) > root {
        c.next_down()
    } else {
        c
    }
}

/// The GPU form of a light.
pub fn light_to_gpu(light: &Light) -> GpuLight {
    match light {
        Light::Directional {
            direction,
            color,
            intensity,
            cast_shadows,
        } => GpuLight {
            position_or_direction: direction.normalize().extend(0.0).to_array(),
            radiance: (*color * *intensity)
                .extend(f32::from(u8::from(*cast_shadows)))
                .to_array(),
        },
        Light::Point {
            position,
            color,
            intensity,
            cast_shadows,
        } => GpuLight {
            position_or_direction: position.extend(1.0).to_array(),
            radiance: (*color * *intensity)
                .extend(f32::from(u8::from(*cast_shadows)))
                .to_array(),
        },
    }
}

/// The GPU form of an instance's transform.
pub fn instance_to_gpu(world_from_object: Mat4, material: usize, shape: usize) -> GpuInstance {
    GpuInstance {
        world_from_object: world_from_object.to_cols_array_2d(),
        object_from_world: world_from_object.inverse().to_cols_array_2d(),
        normal_from_object: world_from_object.inverse().transpose().to_cols_array_2d(),
        material: material as u32,
        shape: shape as u32,
        mirrored: u32::from(world_from_object.determinant() < 0.0),
        _pad: 0,
    }
}

/// Scenes of more than `MAX_INSTANCES` instances are refused: their ids
/// would not fit the G-buffer word the outline search reads.
fn check_instance_count(count: usize) -> Result<(), GpuError> {
    use crate::accel::layout::MAX_INSTANCES;
    if count > MAX_INSTANCES {
        return Err(GpuError::Unsupported(format!(
            "the scene has {count} instances; celray draws at most {MAX_INSTANCES}"
        )));
    }
    Ok(())
}

fn check_limit(what: &str, value: u64, limit: u64) -> Result<(), GpuError> {
    if value > limit {
        Err(GpuError::Limit {
            what: what.to_string(),
            value,
            limit,
        })
    } else {
        Ok(())
    }
}

fn storage_buffer<T: bytemuck::Pod>(gpu: &Gpu, label: &str, data: &[T]) -> wgpu::Buffer {
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(data),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        })
}

/// A uniform copy of a table's `bytes`, zero-padded to the size WGSL
/// declares.
fn uniform_copy(gpu: &Gpu, label: &str, mut contents: Vec<u8>) -> wgpu::Buffer {
    contents.resize(UNIFORM_TABLE_BYTES as usize, 0);
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: &contents,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        })
}

impl SceneBuffers {
    /// Rewrites `table`'s storage buffer `storage` from its start, and its
    /// uniform copy where the passes read that.
    fn write_table(&self, gpu: &Gpu, table: Table, storage: &wgpu::Buffer, bytes: &[u8]) {
        gpu.queue.write_buffer(storage, 0, bytes);
        if self.tables.contains(table) {
            gpu.queue
                .write_buffer(&self.uniform_copies[table as usize], 0, bytes);
        }
    }

    /// Rewrites the materials (as many as at upload).
    pub fn write_materials(&self, gpu: &Gpu, materials: &[GpuMaterial]) {
        self.write_table(
            gpu,
            Table::Materials,
            &self.materials,
            bytemuck::cast_slice(materials),
        );
    }

    /// Rewrites every instance's matrices at shutter fraction `s` (for
    /// motion blur; the top-level BVH already bounds the whole motion).
    pub fn write_instances_at(&self, gpu: &Gpu, scene: &Scene, s: f32) {
        let data: Vec<GpuInstance> = self
            .instance_order
            .iter()
            .map(|&i| {
                let inst = &scene.instances[i];
                instance_to_gpu(inst.world_from_object_at(s), inst.material, inst.shape)
            })
            .collect();
        if !data.is_empty() {
            self.write_table(
                gpu,
                Table::Instances,
                &self.instances,
                bytemuck::cast_slice(&data),
            );
        }
    }

    /// Rewrites the shadow cull data for edited `lights` (as many as at
    /// upload).
    pub fn write_shadow_cull(&mut self, gpu: &Gpu, lights: &[Light]) {
        let cull = shadow_cull::build(&self.accel, lights, self.shadow_lists);
        gpu.queue
            .write_buffer(&self.shadow_cull, 0, bytemuck::cast_slice(&cull.lights));
        gpu.queue
            .write_buffer(&self.shadow_cells, 0, bytemuck::cast_slice(&cull.cells));
        self.sun = cull.sun;
    }

    /// Uploads `scene`. Sizes over the adapter's limits are refused with a
    /// message naming the limit.
    pub fn upload(gpu: &Gpu, scene: &Scene) -> Result<SceneBuffers, GpuError> {
        check_instance_count(scene.instances.len())?;
        let limits = gpu.device.limits();
        let binding_limit = limits.max_storage_buffer_binding_size;

        // Instances sorted by base shape, then by culling: each (shape, cull)
        // group is one contiguous range, drawn by one instanced draw.
        let cull_of = |i: usize| {
            let inst = &scene.instances[i];
            let closed = matches!(
                scene.shapes[inst.shape],
                Shape::Sphere { .. }
                    | Shape::Box { .. }
                    | Shape::Cylinder { .. }
                    | Shape::Cone { .. }
            );
            match (closed, inst.world_from_object.determinant() < 0.0) {
                (false, _) => Cull::None,
                (true, false) => Cull::Back,
                (true, true) => Cull::Front,
            }
        };
        let mut order: Vec<usize> = (0..scene.instances.len()).collect();
        order.sort_by_key(|&i| (scene.instances[i].shape, cull_of(i)));
        let instances: Vec<GpuInstance> = order
            .iter()
            .map(|&i| {
                let inst = &scene.instances[i];
                instance_to_gpu(inst.world_from_object, inst.material, inst.shape)
            })
            .collect();
        check_limit(
            "instance buffer (bytes)",
            (instances.len() * std::mem::size_of::<GpuInstance>()) as u64,
            binding_limit,
        )?;

        let textures = SceneTextures::upload(gpu, scene)?;
        let mut vertices: Vec<Vertex> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        let mut draws = Vec::new();
        let mut triangle_count = 0u64;
        for (shape_id, shape) in scene.shapes.iter().enumerate() {
            let first = order.partition_point(|&i| scene.instances[i].shape < shape_id) as u32;
            let end = order.partition_point(|&i| scene.instances[i].shape <= shape_id) as u32;
            if first == end {
                continue; // a shape nobody instances costs nothing
            }
            if matches!(shape, Shape::Csg(_)) {
                continue; // CSG is ray-traced only: raster mode draws nothing for it
            }
            // Spheres are uploaded at every level of detail, finest first;
            // other shapes have one level, with no inset (meshes are their
            // own truth; boxes and quads are exact).
            let meshes: Vec<(Mesh, f32)> = match shape {
                Shape::Mesh(mesh) => vec![(mesh.clone(), 0.0)],
                Shape::Sphere { radius } => SPHERE_LEVELS
                    .iter()
                    .map(|&segments| {
                        let mesh = tessellate_sphere(*radius, segments);
                        let inset = sphere_inset(&mesh, *radius);
                        (mesh, inset)
                    })
                    .collect(),
                other => vec![(tessellate(other), 0.0)],
            };
            let mut levels = Vec::with_capacity(meshes.len());
            for (mesh, inset) in &meshes {
                levels.push(MeshLevel {
                    first_index: indices.len() as u32,
                    index_count: mesh.indices.len() as u32,
                    base_vertex: vertices.len() as i32,
                    inset: *inset,
                });
                let layers = textures.mesh_layers(mesh);
                vertices.extend(mesh.positions.iter().zip(&mesh.normals).enumerate().map(
                    |(i, (p, n))| Vertex {
                        position: p.to_array(),
                        normal: n.to_array(),
                        uv: mesh.uvs.get(i).copied().unwrap_or_default().to_array(),
                        map: SceneTextures::vertex_layer(&layers, mesh, i),
                    },
                ));
                indices.extend_from_slice(&mesh.indices);
                // The same triangles in reverse order right after
                // (MeshLevel::reversed_first_index).
                indices.extend(mesh.indices.chunks_exact(3).rev().flatten());
            }
            let mut group_start = first;
            while group_start < end {
                let cull = cull_of(order[group_start as usize]);
                let group_end = group_start
                    + order[group_start as usize..end as usize]
                        .iter()
                        .take_while(|&&i| cull_of(i) == cull)
                        .count() as u32;
                draws.push(Draw {
                    shape: shape_id,
                    is_mesh: matches!(shape, Shape::Mesh(_)),
                    cull,
                    levels: levels.clone(),
                    instances: group_start..group_end,
                });
                group_start = group_end;
            }
            triangle_count += (meshes[0].0.indices.len() / 3) as u64 * u64::from(end - first);
        }
        check_limit(
            "vertex buffer (bytes)",
            (vertices.len() * std::mem::size_of::<Vertex>()) as u64,
            limits.max_buffer_size,
        )?;
        check_limit(
            "index buffer (bytes)",
            indices.len() as u64 * 4,
            limits.max_buffer_size,
        )?;
        // Zero-sized buffers cannot be bound: keep one element in each.
        if vertices.is_empty() {
            vertices.push(Vertex {
                position: [0.0; 3],
                normal: [0.0, 1.0, 0.0],
                uv: [0.0; 2],
                map: NO_TEXTURE,
            });
            indices.extend([0, 0, 0]);
        }
        let mut gpu_instances = instances;
        if gpu_instances.is_empty() {
            gpu_instances.push(instance_to_gpu(Mat4::IDENTITY, 0, 0));
        }
        let mut materials: Vec<GpuMaterial> = scene
            .materials
            .iter()
            .map(|m| material_to_gpu(m, &textures))
            .collect();
        if materials.is_empty() {
            materials.push(bytemuck::Zeroable::zeroed());
        }
        let mut lights: Vec<GpuLight> = scene.lights.iter().map(light_to_gpu).collect();
        let light_count = lights.len() as u32;
        if lights.is_empty() {
            lights.push(bytemuck::Zeroable::zeroed());
        }
        check_limit(
            "material buffer (bytes)",
            (materials.len() * std::mem::size_of::<GpuMaterial>()) as u64,
            binding_limit,
        )?;

        let accel =
            SceneAccel::build(scene, &order).map_err(|e| GpuError::Unsupported(e.to_string()))?;
        let mut triangles = accel.triangles.clone();
        if triangles.is_empty() {
            triangles.push(bytemuck::Zeroable::zeroed());
        }
        let mut shapes = accel.shapes.clone();
        if shapes.is_empty() {
            shapes.push(bytemuck::Zeroable::zeroed());
        }
        let mut csg_ops = accel.csg_ops.clone();
        if csg_ops.is_empty() {
            csg_ops.push(bytemuck::Zeroable::zeroed());
        }
        let mut csg_leaves = accel.csg_leaves.clone();
        if csg_leaves.is_empty() {
            csg_leaves.push(bytemuck::Zeroable::zeroed());
        }
        // Per triangle of the trace pass: its mesh's own map layer.
        let mut shape_layers: Vec<Option<Vec<u32>>> = vec![None; scene.shapes.len()];
        let mut triangle_maps: Vec<u32> = accel
            .triangle_sources
            .iter()
            .map(|&(shape, vertex)| match scene.shapes.get(shape as usize) {
                Some(Shape::Mesh(mesh)) if !mesh.textures.is_empty() => {
                    let layers = shape_layers[shape as usize]
                        .get_or_insert_with(|| textures.mesh_layers(mesh));
                    SceneTextures::vertex_layer(layers, mesh, vertex as usize)
                }
                _ => NO_TEXTURE,
            })
            .collect();
        if triangle_maps.is_empty() {
            triangle_maps.push(NO_TEXTURE);
        }
        let mut tlas_items = accel.tlas_items.clone();
        if tlas_items.is_empty() {
            tlas_items.push(0);
        }
        for (what, bytes) in [
            (
                "BVH node buffer (bytes)",
                accel.nodes.len() * std::mem::size_of::<crate::gpu::twins::BvhNode>(),
            ),
            (
                "triangle buffer (bytes)",
                triangles.len() * std::mem::size_of::<crate::gpu::twins::GpuTriangle>(),
            ),
            (
                "CSG leaf buffer (bytes)",
                csg_leaves.len() * std::mem::size_of::<crate::gpu::twins::GpuCsgLeaf>(),
            ),
        ] {
            check_limit(what, bytes as u64, binding_limit)?;
        }

        let table_bytes = |table: Table| -> &[u8] {
            match table {
                Table::Nodes => bytemuck::cast_slice(&accel.nodes),
                Table::Instances => bytemuck::cast_slice(&gpu_instances),
                Table::Shapes => bytemuck::cast_slice(&shapes),
                Table::Materials => bytemuck::cast_slice(&materials),
                Table::CsgOps => bytemuck::cast_slice(&csg_ops),
                Table::CsgLeaves => bytemuck::cast_slice(&csg_leaves),
            }
        };
        let tables = match gpu.uniform_tables() {
            true => UniformTables::fitting(
                |t| table_bytes(t).len(),
                accel.top_nodes * std::mem::size_of::<crate::gpu::twins::BvhNode>(),
            ),
            false => UniformTables::NONE,
        };
        let selected = match gpu.select_tables() {
            true => SelectedTables::of(materials.len(), gpu_instances.len()),
            false => SelectedTables::NONE,
        };
        let packet_trace =
            gpu.packet_walk() && !tables.contains(Table::Nodes) && !tables.top_nodes_only();
        // The contents of the uniform copies (64 KiB at most each): whole
        // tables, or the top-level tree's nodes (the first ones).
        let copies: Vec<Option<Vec<u8>>> = Table::ALL
            .into_iter()
            .map(|t| {
                let top = t == Table::Nodes && tables.top_nodes_only();
                let bytes = table_bytes(t);
                (tables.contains(t) || top)
                    .then(|| bytes[..bytes.len().min(UNIFORM_TABLE_BYTES as usize)].to_vec())
            })
            .collect();

        gpu.scoped(|| {
            let unused = uniform_copy(gpu, "scene table not read (uniform copy)", Vec::new());
            let uniform_copies: Vec<wgpu::Buffer> = Table::ALL
                .into_iter()
                .zip(copies)
                .map(|(t, bytes)| match bytes {
                    Some(bytes) => uniform_copy(gpu, &format!("scene {t:?} (uniform copy)"), bytes),
                    None => unused.clone(),
                })
                .collect();
            let instances = storage_buffer(gpu, "scene instances", &gpu_instances);
            let materials = storage_buffer(gpu, "scene materials", &materials);
            let lights = storage_buffer(gpu, "scene lights", &lights);
            let shapes = storage_buffer(gpu, "scene shapes", &shapes);
            let nodes = storage_buffer(gpu, "scene BVH nodes", &accel.nodes);
            let triangles = storage_buffer(gpu, "scene triangles", &triangles);
            let tlas_items = storage_buffer(gpu, "scene top-level items", &tlas_items);
            let csg_ops = storage_buffer(gpu, "scene CSG programs", &csg_ops);
            let csg_leaves = storage_buffer(gpu, "scene CSG leaves", &csg_leaves);
            let triangle_maps = storage_buffer(gpu, "scene triangle maps", &triangle_maps);
            let shadow_lists = gpu.shadow_lists();
            let cull = shadow_cull::build(&accel, &scene.lights, shadow_lists);
            let shadow_cull = storage_buffer(gpu, "shadow cull", &cull.lights);
            let shadow_cells = storage_buffer(gpu, "shadow cull cells", &cull.cells);
            let mut entries = buffer_entries(&[
                &instances,
                &materials,
                &lights,
                &shapes,
                &nodes,
                &triangles,
                &tlas_items,
                &csg_ops,
                &csg_leaves,
                &triangle_maps,
            ]);
            entries.extend(textures.bind_group_entries(10));
            entries.extend(Table::ALL.into_iter().map(|t| wgpu::BindGroupEntry {
                binding: t.binding(),
                resource: uniform_copies[t as usize].as_entire_binding(),
            }));
            for (binding, buffer) in [(19, &nodes), (20, &triangles)] {
                entries.push(wgpu::BindGroupEntry {
                    binding,
                    resource: buffer.as_entire_binding(),
                });
            }
            let bind_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("scene bind group"),
                layout: &scene_layout(gpu),
                entries: &entries,
            });
            SceneBuffers {
                bind_group,
                shapes,
                nodes,
                triangles,
                tlas_items,
                world_bounds: scene.bounds(),
                has_motion: scene
                    .instances
                    .iter()
                    .any(|i| i.world_from_object_end.is_some()),
                csg_ops,
                csg_leaves,
                triangle_maps,
                shadow_cull,
                shadow_cells,
                sun: cull.sun,
                shadow_lists,
                tables,
                selected,
                packet_trace,
                primary_tiles: gpu.primary_tiles()
                    && accel.instances.len() <= crate::accel::screen_tiles::MAX_TILED_INSTANCES,
                flat_top_level: flat_top_level(gpu, accel.instances.len(), packet_trace),
                uniform_copies,
                accel,
                vertices: gpu
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("scene vertices"),
                        contents: bytemuck::cast_slice(&vertices),
                        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE,
                    }),
                indices: gpu
                    .device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("scene indices"),
                        contents: bytemuck::cast_slice(&indices),
                        usage: wgpu::BufferUsages::INDEX | wgpu::BufferUsages::STORAGE,
                    }),
                instances,
                materials,
                lights,
                light_count,
                textures,
                uses_textures: scene_uses_textures(scene),
                draws,
                instance_order: order,
                triangle_count,
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// 2^24 - 1 instances are drawn (ids up to 2^24 - 1 fit in 24 bits),
    /// one more is refused with a message that names both counts.
    #[test]
    fn scenes_over_the_instance_limit_are_refused() {
        assert!(check_instance_count((1 << 24) - 1).is_ok());
        let message = check_instance_count(1 << 24).unwrap_err().to_string();
        assert!(message.contains("16777216 instances"), "{message}");
        assert!(message.contains("at most 16777215"), "{message}");
    }

    /// The highlight's bound c is the largest f32 not above the root
    /// t^(1/s): every f32 N.H above c passes (N.H)^s > t in exact
    /// arithmetic, and c itself does not. Over thresholds and shininesses
    /// across their ranges, including a root that rounds to 1.0 (t =
    /// 0.99999, s = 1024) and t = 0.
    #[test]
    fn the_highlight_bound_is_the_root_rounded_down() {
        for t in [0.0f32, 1e-6, 0.2, 0.5, 0.6, 0.9, 0.99999, 1.0] {
            for s in [1.0f32, 4.0, 20.0, 32.0, 64.0, 1024.0] {
                let c = highlight_cos(t, s);
                let root = f64::from(t).powf(1.0 / f64::from(s));
                assert!(f64::from(c) <= root, "t {t}, s {s}: {c} above {root}");
                assert!(
                    f64::from(c.next_up()) > root,
                    "t {t}, s {s}: {c} is not the largest f32 below {root}"
                );
                // In the test's own terms, on the f32 N.H on either side.
                let pow = |x: f32| f64::from(x).powf(f64::from(s));
                assert!(pow(c) <= f64::from(t) * (1.0 + 1e-12), "t {t}, s {s}");
                // (At t = 0 the f32 above 0 raised to s underflows f64.)
                if c < 1.0 && t > 0.0 {
                    assert!(pow(c.next_up()) > f64::from(t), "t {t}, s {s}");
                }
            }
        }
        assert_eq!(highlight_cos(0.99999, 1024.0), 1.0f32.next_down());
        assert_eq!(highlight_cos(0.0, 32.0), 0.0);
    }

    /// The shading constants of a scene with `materials` and `lights`
    /// whose instances show the materials named `shown`.
    fn shading_of(materials: &str, lights: &str, shown: &[&str]) -> [(&'static str, f64); 3] {
        let instances: Vec<String> = shown
            .iter()
            .map(|m| format!(r#"(shape: "s", material: "{m}")"#))
            .collect();
        let instances = instances.join(", ");
        let ron = format!(
            r#"(version: 1,
                camera: (eye: (0.0, 0.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: 8, height: 8),
                lights: [{lights}],
                materials: {{ {materials} }},
                shapes: {{ "s": Sphere(radius: 1.0) }},
                instances: [{instances}],
            )"#
        );
        let scene = Scene::from_ron_str(&ron, "test", std::path::Path::new(".")).unwrap();
        ShadingVariant::of(&scene).constants()
    }

    /// Thresholds are bands - 1, four to a vec4; models and light kinds
    /// are bit sets (Blinn-Phong 1, toon 2; directional 1, point 2).
    #[test]
    fn shading_variant_counts_what_materials_and_lights_use() {
        let sun =
            "Directional(direction: (0.0, -1.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 1.0)";
        let bulb = "Point(position: (0.0, 2.0, 0.0), color: (1.0, 1.0, 1.0), intensity: 1.0)";
        let values = |c: [(&str, f64); 3]| c.map(|(_, v)| v);
        assert_eq!(
            values(shading_of(
                r#""a": (base_color: (1.0, 1.0, 1.0), model: Toon(bands: 5))"#,
                sun,
                &["a"]
            )),
            [1.0, 2.0, 1.0]
        );
        assert_eq!(
            values(shading_of(
                r#""a": (base_color: (1.0, 1.0, 1.0), model: Toon(bands: 6)), "b": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong)"#,
                &format!("{sun}, {bulb}"),
                &["a", "b"]
            )),
            [2.0, 3.0, 3.0]
        );
        // A material no instance shows leaves its code out.
        assert_eq!(
            values(shading_of(
                r#""a": (base_color: (1.0, 1.0, 1.0), model: Toon(bands: 16)), "b": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong)"#,
                sun,
                &["b"]
            )),
            [1.0, 1.0, 1.0]
        );
        assert_eq!(
            values(shading_of(
                r#""a": (base_color: (1.0, 1.0, 1.0), model: Toon(bands: 16))"#,
                bulb,
                &["a"]
            )),
            [4.0, 2.0, 2.0]
        );
        assert_eq!(
            values(shading_of(
                r#""a": (base_color: (1.0, 1.0, 1.0), model: BlinnPhong)"#,
                "",
                &["a"]
            )),
            [1.0, 1.0, 3.0]
        );
    }

    fn sun() -> Light {
        Light::Directional {
            direction: Vec3::NEG_Y,
            color: Vec3::ONE,
            intensity: 1.0,
            cast_shadows: true,
        }
    }

    fn bulb() -> Light {
        Light::Point {
            position: Vec3::Y,
            color: Vec3::ONE,
            intensity: 1.0,
            cast_shadows: true,
        }
    }

    /// Up to MAX_FIXED_LIGHTS lights, the count and a bit per point light
    /// at its index; beyond, nothing is fixed.
    #[test]
    fn light_layout_fixes_count_and_kinds_of_few_lights() {
        let constants = |lights: &[Light]| LightLayout::of(lights).constants().map(|(_, v)| v);
        assert_eq!(constants(&[]), [0.0, 0.0]);
        assert_eq!(constants(&[sun(), bulb()]), [2.0, 2.0]);
        assert_eq!(constants(&[bulb(), sun(), bulb()]), [3.0, 5.0]);
        let most = vec![bulb(); MAX_FIXED_LIGHTS as usize];
        assert_eq!(
            constants(&most),
            [
                f64::from(MAX_FIXED_LIGHTS),
                f64::from((1u32 << MAX_FIXED_LIGHTS) - 1)
            ]
        );
        let too_many = vec![bulb(); MAX_FIXED_LIGHTS as usize + 1];
        assert_eq!(constants(&too_many), [f64::from(LIGHTS_DYNAMIC), 0.0]);
    }
}
