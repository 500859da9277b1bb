//! Pass 3: add this sample's colour (with outlines) to the accumulator.
//! Group 0 is the scene's shared group (instances and materials give each
//! pixel's outline); group 1 is [`PASS_LAYOUT`] (frame uniforms, one
//! G-buffer, the accumulator, the tile marks and list). When the scene has
//! outlines, a first dispatch (`shaders/outline_tiles.wgsl`, group 1
//! [`TILES_LAYOUT`], in a compute pass and timer span of its own,
//! "outline_tiles") marks the workgroup tiles where some pixel may take
//! an outline (an outlined object in reach that is not provably the smooth
//! inside of one object) and lists them, counting them into an indirect
//! dispatch. The accumulate pass is then two kernels in one compute pass
//! (timer span "accumulate"): `main` over every tile, which leaves the
//! marked ones, and `outlined`, one workgroup per listed tile, which
//! searches for outlines there (over every tile, the unmarked ones
//! stopping at once, where there are more tiles than a dispatch may
//! count). Apart, the search's code costs nothing to the tiles that do
//! not run it (docs/performance-history.md, seventeenth session).
//! All three kernels read the G-buffer through `shaders/lib/gbuffer.wgsl`:
//! one pipeline each for the raster pass's textures, for the same with
//! the ids in the colour's alpha (override constant `IDS_IN_COLOR`) and
//! for the trace pass's buffers (`TRACED_GBUFFER`), so the trace pass's
//! output is read where it was written, with no copy between
//! ([`GBufferKind`]).

use crate::gpu::layout::{
    read_only_storage_entry, read_write_storage_entry, texture_entry, uniform_entry,
};
use crate::gpu::twins::{
    ACCUMULATE_TILES, MAIN_DISPATCH_WORD, MAX_OUTLINE_RADIUS, OUTLINE_DISPATCH_WORDS,
    OUTLINE_TILES_WORKGROUP, WIDE_OUTLINE_RADIUS,
};
use crate::gpu::{readback, shader, Gpu, GpuError};
use crate::render::scene_buffers::{scene_layout, SceneBuffers, PASS_GROUP, SCENE_GROUP};
use crate::render::targets::Targets;
use wgpu::util::DeviceExt;

const FLOAT: wgpu::TextureSampleType = wgpu::TextureSampleType::Float { filterable: false };

/// Group 1 of the accumulate pass, binding by binding as
/// `shaders/accumulate.wgsl` declares it.
pub const PASS_LAYOUT: [wgpu::BindGroupLayoutEntry; 11] = [
    uniform_entry(0, wgpu::ShaderStages::COMPUTE), // frame
    texture_entry(1, FLOAT),                       // color_tex
    texture_entry(2, FLOAT),                       // normal_depth_tex
    texture_entry(3, wgpu::TextureSampleType::Uint), // id_tex
    read_write_storage_entry(4),                   // accum
    read_only_storage_entry(5, wgpu::ShaderStages::COMPUTE), // tile_marks
    read_only_storage_entry(6, wgpu::ShaderStages::COMPUTE), // traced_color
    read_only_storage_entry(7, wgpu::ShaderStages::COMPUTE), // traced_normal_depth
    read_only_storage_entry(8, wgpu::ShaderStages::COMPUTE), // traced_id
    read_only_storage_entry(9, wgpu::ShaderStages::COMPUTE), // tile_list
    read_only_storage_entry(10, wgpu::ShaderStages::COMPUTE), // outline_dispatch
];

/// Group 1 of the tile-marking dispatch, binding by binding as
/// `shaders/outline_tiles.wgsl` declares it.
/// It holds the whole G-buffer of lib/gbuffer.wgsl, the colour unread.
pub const TILES_LAYOUT: [wgpu::BindGroupLayoutEntry; 11] = [
    uniform_entry(0, wgpu::ShaderStages::COMPUTE), // frame
    texture_entry(1, FLOAT),                       // color_tex
    texture_entry(2, FLOAT),                       // normal_depth_tex
    texture_entry(3, wgpu::TextureSampleType::Uint), // id_tex
    read_write_storage_entry(4),                   // tile_marks
    read_write_storage_entry(5),                   // outline_dispatch
    read_only_storage_entry(6, wgpu::ShaderStages::COMPUTE), // traced_color
    read_only_storage_entry(7, wgpu::ShaderStages::COMPUTE), // traced_normal_depth
    read_only_storage_entry(8, wgpu::ShaderStages::COMPUTE), // traced_id
    read_write_storage_entry(9),                   // tile_list
    read_only_storage_entry(10, wgpu::ShaderStages::COMPUTE), // source_tiles
];

/// Word 3 of the outline dispatch buffer where the `outlined` kernel reads
/// its tiles from the list (`shaders/accumulate.wgsl`).
const OUTLINE_TILES_LISTED: u32 = 1;
/// Byte offset in the outline dispatch buffer of `main`'s indirect
/// dispatch ([`MAIN_DISPATCH_WORD`]), over the tiles the marks left to it
/// where the trace pass accumulates.
const MAIN_DISPATCH_OFFSET: u64 = MAIN_DISPATCH_WORD as u64 * 4;

/// The edge (pixels) of the accumulate pass's tiles, one workgroup each,
/// for a `width` x `height` image whose widest outline is
/// `max_outline_px`: 8 below an outline radius of [`WIDE_OUTLINE_RADIUS`],
/// else 16. Smaller tiles skip more of the image where no outline is near,
/// larger ones load less halo per pixel; on lavapipe the crossing was at
/// 4 px (a 1.5 px outline: marks + accumulate 9.6 ms with 8 px tiles
/// against 12.0 with 16; 8 px outlines: 69 against 61;
/// docs/performance-history.md). An image with more 8 px tiles than one
/// dispatch may count in x (`max_workgroups`, 65,535 on most devices:
/// about 2048 x 2048 pixels, so 3840 x 2160) takes the 16 px tiles too,
/// which the outline marks can still list.
pub fn accumulate_tile_px(
    max_outline_px: f32,
    width: u32,
    height: u32,
    max_workgroups: u32,
) -> u32 {
    let radius = max_outline_px.clamp(0.0, MAX_OUTLINE_RADIUS as f32).floor() as u32;
    let small = ACCUMULATE_TILES[0];
    let small_tiles = u64::from(width.div_ceil(small)) * u64::from(height.div_ceil(small));
    let wide = radius >= WIDE_OUTLINE_RADIUS || small_tiles > u64::from(max_workgroups);
    ACCUMULATE_TILES[usize::from(wide)]
}

/// The accumulate pass's kernels that a sample runs, by what selects
/// them: part of a renderer's pipeline keys ([`crate::render::PipelineKeys`]),
/// since lavapipe compiles each on its first run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Kernels {
    /// The tile edge ([`accumulate_tile_px`]).
    pub tile_px: u32,
    /// Which G-buffer they read, and how.
    pub gbuffer: GBufferKind,
    /// Whether the outline marks and search run (an outline of 1 px or more).
    pub outlines: bool,
}

/// The G-buffer the accumulate kernels and the outline marks read: the
/// raster pass's textures, the same with the ids in the colour's alpha
/// ([`crate::render::raster::ids_in_color`]), or the trace pass's buffers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GBufferKind {
    Raster,
    RasterIdsInColor,
    Traced,
}

impl GBufferKind {
    const ALL: [GBufferKind; 3] = [
        GBufferKind::Raster,
        GBufferKind::RasterIdsInColor,
        GBufferKind::Traced,
    ];

    /// The kernels' override constants `TRACED_GBUFFER` and `IDS_IN_COLOR`.
    fn constants(self) -> [(&'static str, f64); 2] {
        [
            (
                "TRACED_GBUFFER",
                f64::from(u8::from(self == GBufferKind::Traced)),
            ),
            (
                "IDS_IN_COLOR",
                f64::from(u8::from(self == GBufferKind::RasterIdsInColor)),
            ),
        ]
    }

    fn name(self) -> &'static str {
        match self {
            GBufferKind::Raster => "raster",
            GBufferKind::RasterIdsInColor => "raster, ids in colour",
            GBufferKind::Traced => "traced",
        }
    }
}

/// What the pass binds for one tile edge ([`ACCUMULATE_TILES`]).
struct TileGroups {
    /// The accumulate group and the tile-marking group, each with both
    /// G-buffers bound: the pipeline reads one.
    bind_group: wgpu::BindGroup,
    tiles_group: wgpu::BindGroup,
    /// The `outlined` kernel's indirect dispatch (its x counts the marked
    /// tiles; word 3 says whether it is used).
    outline_dispatch: wgpu::Buffer,
    /// Whether `outlined` runs over the listed tiles (indirectly), else
    /// over every tile: an image may have more tiles than one dispatch can
    /// count in x (65,535 on most devices; [`accumulate_tile_px`] takes
    /// the 8 px tiles only where they can be listed, and 16 px tiles are
    /// listed up to about 4096 x 4096 pixels).
    listed: bool,
}

pub struct AccumulatePass {
    /// Per tile edge ([`ACCUMULATE_TILES`]), the `main` kernel reading
    /// each [`GBufferKind`] in the order of `GBufferKind::ALL`.
    pipelines: [[wgpu::ComputePipeline; 3]; 2],
    /// The `outlined` kernel, the same way.
    outline_pipelines: [[wgpu::ComputePipeline; 3]; 2],
    layout: wgpu::BindGroupLayout,
    tiles_pipelines: [[wgpu::ComputePipeline; 3]; 2],
    tiles_layout: wgpu::BindGroupLayout,
    /// The scene's shared group.
    scene_group: Option<wgpu::BindGroup>,
    /// Per tile edge.
    groups: Option<[TileGroups; 2]>,
    /// One word per tile: 1 where the `outlined` kernel searched for
    /// outlines in the last sample (when the scene has outlines); as many
    /// as the smaller tiles need.
    marks: Option<wgpu::Buffer>,
    /// The marked tiles' indices.
    tile_list: Option<wgpu::Buffer>,
    /// Per tile, 0 where the marks may skip it unread
    /// ([`AccumulatePass::write_source_tiles`]), as many as the smaller
    /// tiles need (1 everywhere, as made); and what was last written.
    source_tiles: Option<wgpu::Buffer>,
    written_sources: Vec<u32>,
    /// The kernels that have run ([`AccumulatePass::note_run`]).
    ran: Vec<Kernels>,
    /// The most workgroups a dispatch may count in x.
    max_workgroups: u32,
    /// Workgroups `main` dispatches, looping over its tiles (0: one per
    /// tile; [`Gpu::set_looping_groups`] when the pass was made).
    looping: u32,
    /// The same for `outlined`, whose loop holds barriers: 0 where
    /// [`Gpu::barriers_loop`] says the driver gets that wrong.
    outlined_looping: u32,
}

/// The number of accumulate workgroups (tiles of `tile_px`) of a target,
/// across and down.
fn tiles(targets: &Targets, tile_px: u32) -> (u32, u32) {
    (
        targets.width.div_ceil(tile_px),
        targets.height.div_ceil(tile_px),
    )
}

/// Index of `tile_px` in [`ACCUMULATE_TILES`].
fn edge_index(tile_px: u32) -> usize {
    usize::from(tile_px != ACCUMULATE_TILES[0])
}

impl AccumulatePass {
    pub fn new(gpu: &Gpu) -> Result<AccumulatePass, GpuError> {
        let module = shader::create_module(gpu, "accumulate.wgsl")?;
        let tiles_module = shader::create_module(gpu, "outline_tiles.wgsl")?;
        gpu.scoped(|| {
            let scene_layout = scene_layout(gpu);
            // A kernel's group 1 layout and its pipeline layout.
            let layouts = |name: &str, entries: &[wgpu::BindGroupLayoutEntry]| {
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
                (layout, pipeline_layout)
            };
            // Entry point `entry` of `module`, per tile edge, reading each
            // kind of G-buffer.
            let pipelines =
                |name: &str, pipeline_layout: &wgpu::PipelineLayout, module, entry: &str| {
                    ACCUMULATE_TILES.map(|tile| {
                        GBufferKind::ALL.map(|kind| {
                            let [traced, ids_in_color] = kind.constants();
                            gpu.device
                                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                                    label: Some(&format!(
                                        "{name} pipeline, {entry} ({tile} px tiles, {} G-buffer)",
                                        kind.name()
                                    )),
                                    layout: Some(pipeline_layout),
                                    module,
                                    entry_point: Some(entry),
                                    // The `outlined` kernel writes every texel of
                                    // its workgroup tile before its barrier and reads
                                    // only those (load_tile, outline_at): zeroing the
                                    // tile first would cost every workgroup a pass
                                    // over it and a barrier. (The other kernels have
                                    // no workgroup memory.)
                                    compilation_options: wgpu::PipelineCompilationOptions {
                                        constants: &[
                                            traced,
                                            ids_in_color,
                                            ("ACCUMULATE_TILE", f64::from(tile)),
                                        ],
                                        zero_initialize_workgroup_memory: false,
                                    },
                                    cache: None,
                                })
                        })
                    })
                };
            let (layout, accumulate_layout) = layouts("accumulate", &PASS_LAYOUT);
            let (tiles_layout, tiles_pipeline_layout) = layouts("outline tiles", &TILES_LAYOUT);
            let outline_pipelines =
                pipelines("accumulate", &accumulate_layout, &module, "outlined");
            let tiles_pipelines = pipelines(
                "outline tiles",
                &tiles_pipeline_layout,
                &tiles_module,
                "main",
            );
            let pipelines = pipelines("accumulate", &accumulate_layout, &module, "main");
            AccumulatePass {
                pipelines,
                outline_pipelines,
                layout,
                tiles_pipelines,
                tiles_layout,
                scene_group: None,
                groups: None,
                marks: None,
                tile_list: None,
                source_tiles: None,
                written_sources: Vec::new(),
                ran: Vec::new(),
                max_workgroups: gpu.device.limits().max_compute_workgroups_per_dimension,
                looping: gpu.looping_groups(),
                outlined_looping: if gpu.barriers_loop() {
                    gpu.looping_groups()
                } else {
                    0
                },
            }
        })
    }

    /// Bind groups holding the raster G-buffer (raster mode) and the
    /// traced one (hybrid and raytrace modes), with the tile marks and
    /// list sized to the targets, for each tile edge.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        frame: &wgpu::Buffer,
        scene: &SceneBuffers,
        targets: &Targets,
    ) {
        // The smaller tiles are the more.
        let (most_x, most_y) = tiles(targets, ACCUMULATE_TILES[0]);
        let marks = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("outline tile marks"),
            size: u64::from(most_x * most_y) * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let tile_list = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("outline tile list"),
            size: u64::from(most_x * most_y) * 4,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let source_tiles = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("outline source tiles"),
                contents: bytemuck::cast_slice(&vec![1u32; (most_x * most_y) as usize]),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
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
        let groups = ACCUMULATE_TILES.map(|tile_px| {
            let (tiles_x, tiles_y) = tiles(targets, tile_px);
            // The marks count the listed tiles in x (zeroed before they
            // run); y = z = 1.
            let listed = gpu.outline_tile_list()
                && tiles_x * tiles_y <= gpu.device.limits().max_compute_workgroups_per_dimension;
            // Both dispatches start at x = 0 (the marks count it), y = z = 1.
            let mut start = [0u32; OUTLINE_DISPATCH_WORDS as usize];
            for x in [0, MAIN_DISPATCH_WORD as usize] {
                start[x + 1..x + 3].fill(1);
            }
            start[3] = if listed { OUTLINE_TILES_LISTED } else { 0 };
            let outline_dispatch =
                gpu.device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("outline dispatch"),
                        contents: bytemuck::cast_slice(&start),
                        usage: wgpu::BufferUsages::STORAGE
                            | wgpu::BufferUsages::INDIRECT
                            | wgpu::BufferUsages::COPY_DST,
                    });
            let bind_group = group(
                "accumulate bind group",
                &self.layout,
                &[
                    &shared[..],
                    &[
                        (4, targets.accum.as_entire_binding()),
                        (5, marks.as_entire_binding()),
                        (9, tile_list.as_entire_binding()),
                        (10, outline_dispatch.as_entire_binding()),
                    ],
                ]
                .concat(),
            );
            let tiles_group = group(
                "outline tiles bind group",
                &self.tiles_layout,
                &[
                    &shared[..],
                    &[
                        (4, marks.as_entire_binding()),
                        (5, outline_dispatch.as_entire_binding()),
                        (9, tile_list.as_entire_binding()),
                        (10, source_tiles.as_entire_binding()),
                    ],
                ]
                .concat(),
            );
            TileGroups {
                bind_group,
                tiles_group,
                outline_dispatch,
                listed,
            }
        });
        self.scene_group = Some(scene.bind_group.clone());
        self.groups = Some(groups);
        self.marks = Some(marks);
        self.tile_list = Some(tile_list);
        self.source_tiles = Some(source_tiles);
        self.written_sources.clear();
    }

    /// Uploads the sample's source tiles (`accel::screen_tiles::
    /// reached_tiles`, one word per tile of the edge the sample uses);
    /// nothing where the buffer already holds them.
    pub fn write_source_tiles(&mut self, gpu: &Gpu, sources: Vec<u32>) {
        if let Some(buffer) = &self.source_tiles {
            crate::gpu::write_if_changed(gpu, buffer, &mut self.written_sources, sources);
        }
    }

    /// The source tiles last uploaded (empty before the first, or after
    /// a change of tile edge cleared them). For tests.
    pub fn source_tiles(&self) -> &[u32] {
        &self.written_sources
    }

    /// The tile edge for a `width` x `height` image whose widest outline
    /// is `max_outline_px` ([`accumulate_tile_px`], with this device's
    /// dispatch limit).
    pub fn tile_px(&self, max_outline_px: f32, width: u32, height: u32) -> u32 {
        accumulate_tile_px(max_outline_px, width, height, self.max_workgroups)
    }

    /// Records that a sample runs `kernels`: their code is compiled from
    /// then on.
    pub fn note_run(&mut self, kernels: Kernels) {
        if !self.ran.contains(&kernels) {
            self.ran.push(kernels);
        }
    }

    /// Whether `kernels` have run ([`AccumulatePass::note_run`]): without
    /// outlines only `main` runs, which a sample with outlines also ran.
    pub fn has_run(&self, kernels: Kernels) -> bool {
        let outlined = Kernels {
            outlines: true,
            ..kernels
        };
        self.ran.contains(&kernels) || self.ran.contains(&outlined)
    }

    /// Whether `outlined` runs over the listed tiles of `tile_px` (else
    /// over every tile).
    pub fn listed(&self, tile_px: u32) -> bool {
        self.groups
            .as_ref()
            .is_some_and(|g| g[edge_index(tile_px)].listed)
    }

    /// The tile marks of the last sample, one per accumulate tile of
    /// `tile_px` (the edge that sample used), row by row: 1 where the
    /// outline search ran, 0 where it was skipped. For tests; meaningful
    /// only when the scene has outlines.
    pub fn read_tile_marks(
        &self,
        gpu: &Gpu,
        targets: &Targets,
        tile_px: u32,
    ) -> Result<Vec<u32>, GpuError> {
        let marks = self
            .marks
            .as_ref()
            .ok_or_else(|| GpuError::Readback("the accumulate pass is not prepared".into()))?;
        let bytes = readback::copy_and_read(gpu, marks, marks.size(), "tile marks readback")?;
        let (tiles_x, tiles_y) = tiles(targets, tile_px);
        let words: &[u32] = bytemuck::cast_slice(&bytes);
        Ok(words[..(tiles_x * tiles_y) as usize].to_vec())
    }

    /// The tile marks and list (`shaders/outline_tiles.wgsl`) for tiles of
    /// `tile_px` ([`accumulate_tile_px`]), in a compute pass of their own
    /// (its own timer span, "outline_tiles"). Encode it before
    /// [`AccumulatePass::encode`], with the same tiles, where the scene has
    /// outlines (some material's outline is at least 1 px wide).
    pub fn encode_tiles(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        gbuffer: GBufferKind,
        tile_px: u32,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let Some(groups) = &self.groups else {
            return;
        };
        let edge = edge_index(tile_px);
        // The lists start empty: x = 0 workgroups (y and z stay 1).
        let dispatch = &groups[edge].outline_dispatch;
        encoder.clear_buffer(dispatch, 0, Some(4));
        encoder.clear_buffer(dispatch, MAIN_DISPATCH_OFFSET, Some(4));
        let (tiles_x, tiles_y) = tiles(targets, tile_px);
        let mut pass = self.begin(encoder, "outline tiles pass", timestamp_writes);
        pass.set_pipeline(&self.tiles_pipelines[edge][gbuffer as usize]);
        pass.set_bind_group(PASS_GROUP, &groups[edge].tiles_group, &[]);
        pass.dispatch_workgroups((tiles_x * tiles_y).div_ceil(OUTLINE_TILES_WORKGROUP), 1, 1);
    }

    /// The accumulation over tiles of `kernels.tile_px`: `main` over every
    /// tile the trace pass did not accumulate, then, where the scene has
    /// outlines (and [`AccumulatePass::encode_tiles`] marked and listed
    /// this sample's tiles), `outlined` over the listed tiles (over every
    /// tile where there are too many to list, or where
    /// [`Gpu::set_outline_tile_list`] turned the list off). Where
    /// `trace_accumulates` (the trace pass added the colour of the tiles no
    /// outline reaches) and the list is read, `main` runs over the tiles
    /// the marks left to it alone; else over every tile, skipping the
    /// marked ones.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &Targets,
        kernels: Kernels,
        trace_accumulates: bool,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let Some(groups) = &self.groups else {
            return;
        };
        let Kernels {
            tile_px,
            gbuffer,
            outlines,
        } = kernels;
        let edge = edge_index(tile_px);
        let (tiles_x, tiles_y) = tiles(targets, tile_px);
        let mut pass = self.begin(encoder, "accumulate pass", timestamp_writes);
        pass.set_pipeline(&self.pipelines[edge][gbuffer as usize]);
        pass.set_bind_group(PASS_GROUP, &groups[edge].bind_group, &[]);
        if self.looping > 0 {
            // A few workgroups, each looping over its share of the tiles
            // (as the trace pass): the kernels read the lists' counts.
            pass.dispatch_workgroups(self.looping, 1, 1);
        } else if outlines && trace_accumulates && groups[edge].listed {
            let dispatch = &groups[edge].outline_dispatch;
            pass.dispatch_workgroups_indirect(dispatch, MAIN_DISPATCH_OFFSET);
        } else {
            pass.dispatch_workgroups(tiles_x, tiles_y, 1);
        }
        if outlines {
            pass.set_pipeline(&self.outline_pipelines[edge][gbuffer as usize]);
            if self.outlined_looping > 0 {
                pass.dispatch_workgroups(self.outlined_looping, 1, 1);
            } else if groups[edge].listed {
                pass.dispatch_workgroups_indirect(&groups[edge].outline_dispatch, 0);
            } else {
                pass.dispatch_workgroups(tiles_x, tiles_y, 1);
            }
        }
    }

    /// A compute pass with the scene bound as group 0.
    fn begin<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        label: &str,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> wgpu::ComputePass<'e> {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes,
        });
        pass.set_bind_group(SCENE_GROUP, self.scene_group.as_ref(), &[]);
        pass
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Outlines narrower than 4 px take the 8 px tiles, wider ones (and
    /// widths past the search's cap) the 16 px tiles; no outline at all,
    /// the smaller. At 1280 x 720.
    #[test]
    fn wide_outlines_take_the_larger_tiles() {
        for (width, tile) in [
            (0.0, 8),
            (1.5, 8),
            (3.99, 8),
            (4.0, 16),
            (8.0, 16),
            (100.0, 16),
        ] {
            assert_eq!(
                accumulate_tile_px(width, 1280, 720, 65_535),
                tile,
                "{width} px"
            );
        }
    }

    /// Where one dispatch cannot count the 8 px tiles in x (65,535 here),
    /// the tiles are 16 px, whose count it can: 2560 x 1440 has 320 x 180
    /// = 57,600 small tiles (listed), 3840 x 2160 has 129,600 (not:
    /// 32,400 large ones instead), 2048 x 2040 65,280, 2048 x 2048 exactly 65,536, one too
    /// many; 16384 x 16384 would also dispatch 65,536 marking workgroups
    /// of 64 small tiles.
    #[test]
    fn images_with_too_many_small_tiles_take_the_larger_tiles() {
        for (w, h, tile) in [
            (2560, 1440, 8),
            (3840, 2160, 16),
            (2048, 2040, 8),
            (2048, 2048, 16),
            (16384, 16384, 16),
        ] {
            assert_eq!(accumulate_tile_px(1.5, w, h, 65_535), tile, "{w} x {h}");
        }
    }
}
