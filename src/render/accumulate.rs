//! Pass 3: add this sample's colour (with outlines) to the accumulator.
//! Group 0 is the scene's shared group (instances and materials give each
//! pixel's outline); group 1 is [`PASS_LAYOUT`] (frame uniforms, one
//! G-buffer, the accumulator, the tile marks). When the scene has
//! outlines, a first dispatch (`shaders/outline_tiles.wgsl`, group 1
//! [`TILES_LAYOUT`], in a compute pass and timer span of its own,
//! "outline_tiles") marks the workgroup tiles where some pixel may take
//! an outline (an outlined object in reach that is not provably the smooth
//! inside of one object), and the accumulate kernel searches only those.
//! Both read the G-buffer through `shaders/lib/gbuffer.wgsl`: one pipeline
//! each for the raster pass's textures and one for the trace pass's buffers
//! (override constant `TRACED_GBUFFER`), so the trace pass's output is read
//! where it was written, with no copy between.

use crate::gpu::layout::{
    read_only_storage_entry, read_write_storage_entry, texture_entry, uniform_entry,
};
use crate::gpu::twins::{ACCUMULATE_WORKGROUP, OUTLINE_TILES_WORKGROUP};
use crate::gpu::{readback, shader, Gpu, GpuError};
use crate::render::scene_buffers::{scene_layout, SceneBuffers, PASS_GROUP, SCENE_GROUP};
use crate::render::targets::Targets;

const FLOAT: wgpu::TextureSampleType = wgpu::TextureSampleType::Float { filterable: false };

/// Group 1 of the accumulate pass, binding by binding as
/// `shaders/accumulate.wgsl` declares it.
pub const PASS_LAYOUT: [wgpu::BindGroupLayoutEntry; 9] = [
    uniform_entry(0, wgpu::ShaderStages::COMPUTE), // frame
    texture_entry(1, FLOAT),                       // color_tex
    texture_entry(2, FLOAT),                       // normal_depth_tex
    texture_entry(3, wgpu::TextureSampleType::Uint), // id_tex
    read_write_storage_entry(4),                   // accum
    read_only_storage_entry(5, wgpu::ShaderStages::COMPUTE), // tile_marks
    read_only_storage_entry(6, wgpu::ShaderStages::COMPUTE), // traced_color
    read_only_storage_entry(7, wgpu::ShaderStages::COMPUTE), // traced_normal_depth
    read_only_storage_entry(8, wgpu::ShaderStages::COMPUTE), // traced_id
];

/// Group 1 of the tile-marking dispatch, binding by binding as
/// `shaders/outline_tiles.wgsl` declares it.
/// It holds the whole G-buffer of lib/gbuffer.wgsl, the colour unread.
pub const TILES_LAYOUT: [wgpu::BindGroupLayoutEntry; 8] = [
    uniform_entry(0, wgpu::ShaderStages::COMPUTE), // frame
    texture_entry(1, FLOAT),                       // color_tex
    texture_entry(2, FLOAT),                       // normal_depth_tex
    texture_entry(3, wgpu::TextureSampleType::Uint), // id_tex
    read_write_storage_entry(4),                   // tile_marks
    read_only_storage_entry(6, wgpu::ShaderStages::COMPUTE), // traced_color
    read_only_storage_entry(7, wgpu::ShaderStages::COMPUTE), // traced_normal_depth
    read_only_storage_entry(8, wgpu::ShaderStages::COMPUTE), // traced_id
];

pub struct AccumulatePass {
    /// Reading the raster G-buffer, then the traced one.
    pipelines: [wgpu::ComputePipeline; 2],
    layout: wgpu::BindGroupLayout,
    tiles_pipelines: [wgpu::ComputePipeline; 2],
    tiles_layout: wgpu::BindGroupLayout,
    /// The scene's shared group.
    scene_group: Option<wgpu::BindGroup>,
    /// The accumulate group and the tile-marking group, each with both
    /// G-buffers bound: the pipeline reads one.
    bind_group: Option<wgpu::BindGroup>,
    tiles_group: Option<wgpu::BindGroup>,
    /// One word per tile: 1 where the accumulate kernel searched for
    /// outlines in the last sample (when the scene has outlines).
    marks: Option<wgpu::Buffer>,
}

/// The number of accumulate workgroups (tiles) of a target, across and down.
fn tiles(targets: &Targets) -> (u32, u32) {
    (
        targets.width.div_ceil(ACCUMULATE_WORKGROUP),
        targets.height.div_ceil(ACCUMULATE_WORKGROUP),
    )
}

impl AccumulatePass {
    pub fn new(gpu: &Gpu) -> Result<AccumulatePass, GpuError> {
        let module = shader::create_module(gpu, "accumulate.wgsl")?;
        let tiles_module = shader::create_module(gpu, "outline_tiles.wgsl")?;
        gpu.scoped(|| {
            let scene_layout = scene_layout(gpu);
            let kernel = |name: &str, entries: &[wgpu::BindGroupLayoutEntry], module| {
                let layout =
                    gpu.device
                        .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                            label: Some(&format!("{name} bind group layout")),
                            entries,
                        });
                let pipeline_layout =
                    gpu.device
                        .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                            label: Some(&format!("{name} pipeline layout")),
                            bind_group_layouts: &[Some(&scene_layout), Some(&layout)],
                            immediate_size: 0,
                        });
                let pipeline = |traced: bool| {
                    gpu.device
                        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                            label: Some(&format!(
                                "{name} pipeline ({} G-buffer)",
                                if traced { "traced" } else { "raster" }
                            )),
                            layout: Some(&pipeline_layout),
                            module,
                            entry_point: Some("main"),
                            // The accumulate kernel writes every texel of
                            // its workgroup tile before its barrier and reads
                            // only those (load_tile, outline_at): zeroing the
                            // tile first would cost every workgroup a pass
                            // over it and a barrier, marked or not. (The
                            // outline marks have no workgroup memory.)
                            compilation_options: wgpu::PipelineCompilationOptions {
                                constants: &[("TRACED_GBUFFER", f64::from(u8::from(traced)))],
                                zero_initialize_workgroup_memory: false,
                            },
                            cache: None,
                        })
                };
                ([pipeline(false), pipeline(true)], layout)
            };
            let (pipelines, layout) = kernel("accumulate", &PASS_LAYOUT, &module);
            let (tiles_pipelines, tiles_layout) =
                kernel("outline tiles", &TILES_LAYOUT, &tiles_module);
            AccumulatePass {
                pipelines,
                layout,
                tiles_pipelines,
                tiles_layout,
                scene_group: None,
                bind_group: None,
                tiles_group: None,
                marks: None,
            }
        })
    }

    /// Bind groups holding the raster G-buffer (raster mode) and the
    /// traced one (hybrid and raytrace modes), with the tile marks sized
    /// to the targets.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        frame: &wgpu::Buffer,
        scene: &SceneBuffers,
        targets: &Targets,
    ) {
        let (tiles_x, tiles_y) = tiles(targets);
        let marks = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("outline tile marks"),
            size: u64::from(tiles_x * tiles_y) * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let group = |label, layout, entries: &[(u32, wgpu::BindingResource)]| {
            let entries: Vec<_> = entries
                .iter()
                .map(|(binding, resource)| wgpu::BindGroupEntry {
                    binding: *binding,
                    resource: resource.clone(),
                })
                .collect();
            gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout,
                entries: &entries,
            })
        };
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (raster, traced) = (&targets.raster, &targets.traced_output);
        let (color, normal_depth, id) = (
            view(&raster.color),
            view(&raster.normal_depth),
            view(&raster.id),
        );
        // Bindings 0-3 and 6-8 of both groups: the frame and the G-buffer
        // of lib/gbuffer.wgsl; each adds its own (4 and up).
        let shared = [
            (0, frame.as_entire_binding()),
            (1, wgpu::BindingResource::TextureView(&color)),
            (2, wgpu::BindingResource::TextureView(&normal_depth)),
            (3, wgpu::BindingResource::TextureView(&id)),
            (6, traced.color.as_entire_binding()),
            (7, traced.normal_depth.as_entire_binding()),
            (8, traced.id.as_entire_binding()),
        ];
        self.scene_group = Some(scene.bind_group.clone());
        self.bind_group = Some(group(
            "accumulate bind group",
            &self.layout,
            &[
                &shared[..],
                &[
                    (4, targets.accum.as_entire_binding()),
                    (5, marks.as_entire_binding()),
                ],
            ]
            .concat(),
        ));
        self.tiles_group = Some(group(
            "outline tiles bind group",
            &self.tiles_layout,
            &[&shared[..], &[(4, marks.as_entire_binding())]].concat(),
        ));
        self.marks = Some(marks);
    }

    /// The tile marks of the last sample, one per accumulate tile, row by
    /// row: 1 where the outline search ran, 0 where it was skipped. For
    /// tests; meaningful only when the scene has outlines.
    pub fn read_tile_marks(&self, gpu: &Gpu) -> Result<Vec<u32>, GpuError> {
        let marks = self
            .marks
            .as_ref()
            .ok_or_else(|| GpuError::Readback("the accumulate pass is not prepared".into()))?;
        let bytes = readback::copy_and_read(gpu, marks, marks.size(), "tile marks readback")?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }

    /// The tile marks (`shaders/outline_tiles.wgsl`), in a compute pass of
    /// their own (its own timer span, "outline_tiles"). Encode it before
    /// [`AccumulatePass::encode`] where the scene has outlines (some
    /// material's outline is at least 1 px wide).
    pub fn encode_tiles(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        traced: bool,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let (tiles_x, tiles_y) = tiles(targets);
        self.dispatch(
            encoder,
            "outline tiles pass",
            &self.tiles_pipelines[usize::from(traced)],
            self.tiles_group.as_ref(),
            ((tiles_x * tiles_y).div_ceil(OUTLINE_TILES_WORKGROUP), 1),
            timestamp_writes,
        );
    }

    /// The accumulation, with the outline search where the scene has
    /// outlines (it reads the marks [`AccumulatePass::encode_tiles`] wrote
    /// this sample).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        traced: bool,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        self.dispatch(
            encoder,
            "accumulate pass",
            &self.pipelines[usize::from(traced)],
            self.bind_group.as_ref(),
            tiles(targets),
            timestamp_writes,
        );
    }

    /// One compute pass of one dispatch, with the scene as group 0 and
    /// `group` as group 1.
    fn dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        group: Option<&wgpu::BindGroup>,
        (x, y): (u32, u32),
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes,
        });
        pass.set_bind_group(SCENE_GROUP, self.scene_group.as_ref(), &[]);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(PASS_GROUP, group, &[]);
        pass.dispatch_workgroups(x, y, 1);
    }
}
