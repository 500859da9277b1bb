//! The renderer: the passes of a frame, one sample at a time, averaged in
//! the accumulation buffer. Knows scene, sampling, accel and gpu; never
//! winit or egui.
//!
//! Per sample k: (1) the raster pass shades what it draws (every instance
//! in raster mode, the meshes in hybrid mode) into the G-buffer
//! with the projection jittered to sample k's sub-pixel position; (3) the
//! accumulate pass adds the G-buffer colour, with outlines, to the float
//! accumulator; in hybrid and raytrace modes (2) the trace pass, between
//! them, traces what the raster pass cannot draw (see [`trace`]); while
//! the view moves with temporal reprojection on, (3b) the reproject pass
//! blends the sample into the reprojected history (see [`reproject`]). On
//! demand, (4) a resolve pass turns the average into a displayable image:
//! the renderer owns one per target format ([`Renderer::resolve_into`]).
//! [`Renderer::pick`] answers "what is under this ray" with the CPU copy of
//! the scene's acceleration structure, and a [`GpuTimer`] times the passes
//! when asked ([`Renderer::enable_pass_timing`]).

pub mod accumulate;
pub mod camera;
pub mod driver_accel;
pub mod raster;
pub mod ray_batch;
pub mod reproject;
pub mod resolve;
pub mod scene_buffers;
pub mod settings;
pub mod targets;
pub mod textures;
pub mod trace;
pub mod warmup;

use wgpu::util::DeviceExt;

use crate::gpu::timer::{GpuTimer, Span};
use crate::gpu::twins::{
    FrameUniforms, ReprojectUniforms, OUTLINE_MARK_SEARCH, SHAPE_MESH, TEMPORAL_REJECT_CLIP,
    TEMPORAL_REJECT_NONE, TILE_GBUFFER_SKIPS, TILE_MESH_MAY_SHOW, TILE_RECORD_SHIFT,
    TILE_TRACE_ACCUMULATES, TILE_UNSHADOWED, TRACE_WORKGROUP,
};
use crate::gpu::{readback, Gpu, GpuError};
use crate::sampling::{Sample, SampleSchedule};
use crate::scene::Scene;
use accumulate::AccumulatePass;
use driver_accel::DriverAccel;
use raster::RasterPass;
use reproject::ReprojectPass;
use resolve::ResolvePass;
use scene_buffers::SceneBuffers;
pub use settings::{
    AccelChoice, RenderMode, RenderSettings, Temporal, ToneMap, MAX_BOUNCES, MAX_IMAGE_SAMPLES,
    MAX_SPP,
};
use targets::Targets;
use trace::TracePass;

/// The passes [`Renderer::pass_times`] reports, in this order, each when
/// the last timed sample ran it (no trace in raster mode; outline_tiles, the
/// accumulate pass's marking dispatch, only where some outline is 1 px or
/// wider; reproject only after a moving frame).
pub const PASS_NAMES: [&str; 5] = [
    "raster",
    "trace",
    "outline_tiles",
    "accumulate",
    "reproject",
];

/// The widest outline of `scene`'s instances (an outline's width is its
/// instance's material's, a CSG leaf's material has none of its own), in
/// pixels, capped at the accumulate pass's search radius.
fn max_outline_px(scene: &Scene) -> f32 {
    let materials = scene.instances.iter().map(|i| &scene.materials[i.material]);
    materials
        .map(|m| m.outline_width_px)
        .fold(0.0f32, f32::max)
        .min(crate::gpu::twins::MAX_OUTLINE_RADIUS as f32)
}

/// Sets `TILE_GBUFFER_SKIPS` in the flag words that follow the records in
/// `tiles` (the trace tiles of an image of `settings`' size) where no pass
/// of the sample reads the tile's traced normal, depth and id: the trace
/// pass accumulates the tile (`TILE_TRACE_ACCUMULATES`), and no accumulate
/// tile of `tile_px` whose outline marks and search run (its `sources`
/// word is not 0; none without outlines) lies within the outline radius of
/// it, as far as those read around their own tile
/// (shaders/outline_tiles.wgsl, shaders/accumulate.wgsl). Returns whether
/// some tile skips.
fn flag_gbuffer_skips(
    tiles: &mut [u32],
    scene: &Scene,
    settings: &RenderSettings,
    sources: Option<&[u32]>,
    tile_px: u32,
) -> bool {
    let size = (settings.width, settings.height);
    let trace_x = size.0.div_ceil(TRACE_WORKGROUP);
    let count = (trace_x * size.1.div_ceil(TRACE_WORKGROUP)) as usize;
    let flags = tiles.len() - count;
    let grid = (size.0.div_ceil(tile_px), size.1.div_ceil(tile_px));
    let r = max_outline_px(scene).floor() as u32;
    // Whether an accumulate tile that reads the G-buffer lies within r of
    // the trace tile at pixel (x, y).
    let read_near = |s: &[u32], x: u32, y: u32| {
        let lo = (x.saturating_sub(r) / tile_px, y.saturating_sub(r) / tile_px);
        let edge = TRACE_WORKGROUP - 1 + r;
        let hi = (
            ((x + edge) / tile_px).min(grid.0 - 1),
            ((y + edge) / tile_px).min(grid.1 - 1),
        );
        (lo.1..=hi.1).any(|ty| (lo.0..=hi.0).any(|tx| s[(ty * grid.0 + tx) as usize] != 0))
    };
    let mut any = false;
    for (t, word) in (0u32..).zip(tiles[flags..].iter_mut()) {
        let (x, y) = (
            (t % trace_x) * TRACE_WORKGROUP,
            (t / trace_x) * TRACE_WORKGROUP,
        );
        if *word & TILE_TRACE_ACCUMULATES != 0 && !sources.is_some_and(|s| read_near(s, x, y)) {
            *word |= TILE_GBUFFER_SKIPS;
            any = true;
        }
    }
    any
}

/// The pipelines a renderer draws with, by their cache keys: the raster
/// and trace variants, whether rays walk the driver's structures, whether
/// moving frames run the reproject pass (temporal reprojection on), and
/// the accumulate kernels. A change that needs new ones pays for their
/// compilation on its first frame ([`Renderer::has_pipelines`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PipelineKeys {
    raster: raster::RasterVariant,
    trace: trace::Variant,
    driver: bool,
    reproject: bool,
    accumulate: accumulate::Kernels,
}

/// GPU time of a sample's passes: one timer, one span per pass.
struct SampleTimer {
    timer: GpuTimer,
    /// Whether the last sample was timed (its round had a free slot).
    last_timed: bool,
    /// Whether samples are timed at all ([`Renderer::time_samples`]).
    on: bool,
    raster: Span,
    trace: Span,
    outline_tiles: Span,
    accumulate: Span,
    reproject: Span,
}

impl SampleTimer {
    fn new(gpu: &Gpu) -> Option<SampleTimer> {
        let (timer, [raster, trace, outline_tiles, accumulate, reproject]) =
            GpuTimer::new(gpu, "sample passes", PASS_NAMES)?;
        Some(SampleTimer {
            timer,
            last_timed: false,
            on: true,
            raster,
            trace,
            outline_tiles,
            accumulate,
            reproject,
        })
    }
}

/// The most samples a reprojected history counts while the view moves: the
/// blend weight of a new sample never drops below 1 / (this + 1), so the
/// blur that resampling adds each frame fades. Measured on the orbit test
/// (FLIP against 256 samples, 96x64 and 192x128): 4 beat 3, 5, 8 and 16.
pub const TEMPORAL_MAX_HISTORY: f32 = 4.0;

/// The static quads and disks whose tiles are proven unshadowed
/// ([`Renderer::flag_unshadowed`]): the first ones, in GPU instance order.
const UNSHADOWED_PLANES: usize = 4;
/// Half-width of the neighbourhood clipping box, in standard deviations
/// (1.5 measured best of 0.75, 1.0, 1.25, 1.5 on the same test).
pub const TEMPORAL_CLIP_GAMMA: f32 = 1.5;
/// The history is rejected where the previous frame's view depth differs
/// from the reprojected point's by more than this fraction.
pub const TEMPORAL_DEPTH_TOLERANCE: f32 = 0.05;

/// A frame's camera without jitter or lens offset: what motion vectors and
/// the history are measured against.
#[derive(Debug, Clone, Copy)]
struct ViewMatrices {
    clip_from_world: glam::Mat4,
    eye: glam::Vec3,
    forward: glam::Vec3,
}

/// The temporal accumulation's state between frames.
#[derive(Debug, Default)]
struct TemporalState {
    /// The last rendered frame's camera; None after a reset (no history).
    last_view: Option<ViewMatrices>,
    /// The camera changed since the last frame: the next one reprojects.
    moved: bool,
    /// Sample-schedule index of the next moving frame.
    next_k: u32,
    /// Whether the last frame was a moving one.
    last_moved: bool,
}

pub struct Renderer {
    scene: Scene,
    settings: RenderSettings,
    buffers: SceneBuffers,
    targets: Targets,
    frame: wgpu::Buffer,
    raster: RasterPass,
    trace: TracePass,
    accumulate: AccumulatePass,
    /// One resolve pass per target format asked for (the capture format
    /// first), each kept bound to the current accumulator and settings by
    /// [`Renderer::bind`].
    resolves: Vec<ResolvePass>,
    /// The temporal pass, built when `settings.temporal` is not Off.
    reproject: Option<ReprojectPass>,
    temporal: TemporalState,
    /// Exact samples in the accumulator; 0 after any change (and after a
    /// moving frame, whose accumulator holds the reprojected history).
    samples: u32,
    /// GPU time per pass, when enabled and the adapter has timestamps.
    timer: Option<SampleTimer>,
    /// The driver's acceleration structures, when rays walk them
    /// (`settings.accel`); `None` on the software BVH.
    driver: Option<DriverAccel>,
    /// Why the driver path was asked for but not taken (one line).
    accel_notice: Option<String>,
    /// The accumulate tile edge [`Renderer::use_pipelines`] or
    /// [`Renderer::use_tiles_of_size`] set, in place of the one the image's
    /// size and outlines choose.
    tile_px: Option<u32>,
    /// Whether the trace pass may add the colour of the tiles no outline
    /// reaches to the accumulator itself, where it reads primary tiles
    /// ([`Gpu::set_trace_accumulates`] when the renderer was made).
    trace_may_accumulate: bool,
    /// Whether the outline marks skip the tiles the CPU proves the smooth
    /// inside of one sphere or plane ([`Gpu::set_smooth_tiles`] when the
    /// renderer was made).
    smooth_tiles: bool,
    /// The last sample's frame uniforms, where its trace pass left the
    /// normal, depth and id of some tiles unstored (`TILE_GBUFFER_SKIPS`:
    /// no pass of that sample read them); [`Renderer::complete_gbuffer`]
    /// stores them before anything reads the G-buffer in full.
    partial_gbuffer: Option<FrameUniforms>,
    /// What the tiles last uploaded were made for
    /// ([`Renderer::sample_tiles`]), and whether some tile of them skips
    /// its G-buffer stores; cleared by every change.
    tile_cache: Option<(TileKey, bool)>,
}

/// What a sample's outline source tiles and primary tiles are made for:
/// the same key, the same tiles.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TileKey {
    clip_from_world: [f32; 16],
    mode: RenderMode,
    tile_px: u32,
    outlines: bool,
    reads_tiles: bool,
    still: bool,
}

/// A sample's outline source tiles and primary tiles, where it uses them,
/// and whether some tile skips its G-buffer stores.
struct SampleTiles {
    sources: Option<Vec<u32>>,
    tiles: Option<Vec<u32>>,
    skips: bool,
}

/// The driver's structures for `scene` where `settings.accel` asks for them
/// (`auto`: where [`AccelChoice::driver_preferred`]) and the ray-traced
/// passes run; else `None`, with a one-line notice when the driver path was
/// wanted but cannot serve (the image is then the software path's).
fn choose_driver(
    gpu: &Gpu,
    scene: &Scene,
    buffers: &SceneBuffers,
    settings: &RenderSettings,
) -> (Option<DriverAccel>, Option<String>) {
    let wanted = match settings.accel {
        AccelChoice::Software => false,
        AccelChoice::Driver => true,
        AccelChoice::Auto => {
            gpu.has_ray_queries()
                && AccelChoice::driver_preferred(gpu.adapter.get_info().device_type)
        }
    };
    if !wanted || settings.mode == RenderMode::Raster {
        return (None, None);
    }
    match DriverAccel::build(gpu, scene, buffers) {
        Ok(d) => (Some(d), None),
        Err(reason) => {
            let notice =
                format!("driver ray queries not used: {reason}; tracing with the software BVH");
            log::warn!("{notice}");
            (None, Some(notice))
        }
    }
}

impl Renderer {
    /// Builds the passes and uploads `scene`.
    pub fn new(gpu: &Gpu, scene: Scene, settings: RenderSettings) -> Result<Renderer, GpuError> {
        let buffers = SceneBuffers::upload(gpu, &scene)?;
        log::info!(
            "scene: {} instances, {} draws, {} triangles",
            scene.instances.len(),
            buffers.draws.len(),
            buffers.triangle_count
        );
        let targets = Targets::new(gpu, settings.width, settings.height)?;
        let frame = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("frame uniforms"),
                contents: bytemuck::bytes_of(&<FrameUniforms as bytemuck::Zeroable>::zeroed()),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        let (driver, accel_notice) = choose_driver(gpu, &scene, &buffers, &settings);
        let mut renderer = Renderer {
            raster: RasterPass::new(gpu)?,
            trace: TracePass::new(gpu)?,
            accumulate: AccumulatePass::new(gpu)?,
            resolves: vec![ResolvePass::new(gpu, targets::CAPTURE_FORMAT)?],
            scene,
            settings,
            buffers,
            targets,
            frame,
            samples: 0,
            timer: None,
            driver,
            accel_notice,
            reproject: None,
            temporal: TemporalState::default(),
            tile_px: None,
            trace_may_accumulate: gpu.trace_accumulates(),
            smooth_tiles: gpu.smooth_tiles(),
            partial_gbuffer: None,
            tile_cache: None,
        };
        renderer.bind(gpu)?;
        Ok(renderer)
    }

    fn bind(&mut self, gpu: &Gpu) -> Result<(), GpuError> {
        self.tile_cache = None;
        let raster = RasterPass::variant_of(&self.scene, &self.buffers, &self.settings);
        self.raster.prepare(gpu, &self.frame, raster);
        let variant = trace::Variant::of(&self.scene, &self.buffers, &self.settings);
        let traced = self.trace.prepare(
            gpu,
            &self.frame,
            &self.buffers,
            &self.targets,
            self.driver.as_ref(),
            variant,
        );
        if let Err(e) = traced {
            // A driver variant that does not build (its shader or pipeline)
            // falls back to the software BVH with the notice; the software
            // variant failing is an error as before.
            if self.driver.take().is_none() {
                return Err(e);
            }
            let words: Vec<String> = e.to_string().split_whitespace().map(String::from).collect();
            let notice = format!(
                "driver ray queries not used: the driver trace pipeline failed: {}; tracing with the software BVH",
                words.join(" ")
            );
            log::warn!("{notice}");
            self.accel_notice = Some(notice);
            self.trace.prepare(
                gpu,
                &self.frame,
                &self.buffers,
                &self.targets,
                None,
                variant,
            )?;
        }
        self.accumulate
            .prepare(gpu, &self.frame, &self.buffers, &self.targets);
        for pass in &mut self.resolves {
            pass.prepare(gpu, &self.settings, &self.targets)?;
        }
        if self.settings.temporal == Temporal::Off {
            self.reproject = None;
        } else {
            if self.reproject.is_none() {
                self.reproject = Some(ReprojectPass::new(gpu)?);
            }
            if let Some(pass) = &mut self.reproject {
                pass.prepare(gpu, &self.frame, &self.targets)?;
            }
        }
        Ok(())
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    pub fn scene_buffers(&self) -> &SceneBuffers {
        &self.buffers
    }

    /// The trace pass's variant now (which code its kernel holds).
    pub fn trace_variant(&self) -> trace::Variant {
        self.trace.variant()
    }

    /// Which acceleration structure rays walk now: "driver" or "software".
    pub fn accel_in_use(&self) -> &'static str {
        if self.trace.uses_driver() {
            "driver"
        } else {
            "software"
        }
    }

    /// Why the driver path was asked for but is not used, if it is not.
    pub fn accel_notice(&self) -> Option<&str> {
        self.accel_notice.as_deref()
    }

    /// The driver's structures, when rays walk them.
    pub fn driver_accel(&self) -> Option<&DriverAccel> {
        self.driver.as_ref()
    }

    /// Distance along `dir` (a unit vector) from `origin`, in world units,
    /// to the closest surface of the scene, if any: what is under a ray,
    /// found on the CPU in the acceleration structure built for the GPU
    /// (no new build).
    pub fn pick(&self, origin: glam::Vec3, dir: glam::Vec3) -> Option<f32> {
        let hit = self
            .buffers
            .accel
            .closest_hit(origin, dir, 0.0, f32::MAX)
            .hit?;
        Some(hit.t)
    }

    /// Samples averaged so far.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// True once the accumulator holds `settings.spp` samples.
    pub fn converged(&self) -> bool {
        self.samples >= self.settings.spp
    }

    /// The one place accumulation restarts: every change calls this.
    pub fn reset(&mut self) {
        self.samples = 0;
        self.temporal.last_view = None;
        self.temporal.moved = false;
        self.partial_gbuffer = None;
        self.tile_cache = None;
    }

    /// Replaces the scene (uploading it again) and restarts accumulation.
    pub fn set_scene(&mut self, gpu: &Gpu, scene: Scene) -> Result<(), GpuError> {
        // Even where a step below fails: the last sample's G-buffer is
        // not completed against another scene.
        self.partial_gbuffer = None;
        self.tile_cache = None;
        self.buffers = SceneBuffers::upload(gpu, &scene)?;
        (self.driver, self.accel_notice) =
            choose_driver(gpu, &scene, &self.buffers, &self.settings);
        self.scene = scene;
        self.bind(gpu)?;
        self.reset();
        Ok(())
    }

    /// Replaces the scene and restarts accumulation. When only materials,
    /// lights, camera, ambient or background differ from the current scene
    /// (same shapes, instances and counts), those are written in place;
    /// otherwise everything is uploaded again as in [`Renderer::set_scene`].
    pub fn update_scene(&mut self, gpu: &Gpu, scene: Scene) -> Result<(), GpuError> {
        self.partial_gbuffer = None;
        self.tile_cache = None;
        if !self.edits_in_place(&scene) {
            return self.set_scene(gpu, scene);
        }
        if !scene.materials.is_empty() {
            let materials: Vec<_> = scene
                .materials
                .iter()
                .map(|m| scene_buffers::material_to_gpu(m, &self.buffers.textures))
                .collect();
            self.buffers.write_materials(gpu, &materials);
        }
        if !scene.lights.is_empty() {
            let lights: Vec<_> = scene
                .lights
                .iter()
                .map(scene_buffers::light_to_gpu)
                .collect();
            gpu.queue
                .write_buffer(&self.buffers.lights, 0, bytemuck::cast_slice(&lights));
            self.buffers.write_shadow_cull(gpu, &scene.lights);
        }
        self.scene = scene;
        // Edited materials or lights may need other code in the kernels
        // (e.g. a first reflective material).
        let keys = self.keys_after_edit(&self.scene);
        self.raster.prepare(gpu, &self.frame, keys.raster);
        self.trace.select_variant(gpu, keys.trace)?;
        self.reset();
        Ok(())
    }

    /// Whether [`Renderer::update_scene`] can write `scene` in place: only
    /// materials, lights, camera, ambient or background differ (same
    /// shapes, instances and counts).
    fn edits_in_place(&self, scene: &Scene) -> bool {
        scene.shapes == self.scene.shapes
            && scene.instances == self.scene.instances
            && scene.materials.len() == self.scene.materials.len()
            && scene.lights.len() == self.scene.lights.len()
            && textures::scene_uses_textures(scene) == self.buffers.uses_textures
            && textures::scene_images(scene) == self.buffers.textures.layers
    }

    /// The pipelines the renderer draws with now.
    pub fn pipeline_keys(&self) -> PipelineKeys {
        PipelineKeys {
            raster: self.raster.variant(),
            trace: self.trace.variant(),
            driver: self.trace.uses_driver(),
            reproject: self.settings.temporal != Temporal::Off,
            accumulate: self.accumulate_kernels(&self.scene, &self.settings),
        }
    }

    /// Whether the renderer has built every pipeline of `keys` (on a
    /// pipeline's first run, a driver that compiles lazily, as lavapipe
    /// does, compiles it: seconds on the CPU driver). The accumulate
    /// kernels are all built up front, so theirs count once they have run
    /// (or are the ones the renderer draws with now, which its next
    /// sample runs).
    pub fn has_pipelines(&self, keys: &PipelineKeys) -> bool {
        let now = self.accumulate_kernels(&self.scene, &self.settings);
        keys.driver == self.trace.uses_driver()
            && self.raster.has_variant(keys.raster)
            && self.trace.has_variant(keys.trace)
            && (!keys.reproject || self.reproject.is_some())
            && (keys.accumulate == now || self.accumulate.has_run(keys.accumulate))
    }

    /// The accumulate kernels a sample of `scene` with `settings` runs.
    fn accumulate_kernels(&self, scene: &Scene, settings: &RenderSettings) -> accumulate::Kernels {
        let widest = max_outline_px(scene);
        accumulate::Kernels {
            tile_px: self.tile_px.unwrap_or_else(|| {
                (self.accumulate).tile_px(widest, settings.width, settings.height)
            }),
            gbuffer: if settings.mode != RenderMode::Raster {
                accumulate::GBufferKind::Traced
            } else if raster::ids_in_color(scene.instances.len(), settings) {
                accumulate::GBufferKind::RasterIdsInColor
            } else {
                accumulate::GBufferKind::Raster
            },
            outlines: widest >= 1.0,
        }
    }

    /// The pipelines [`Renderer::update_scene`]`(scene)` would draw with,
    /// where it writes `scene` in place; `None` where it would upload the
    /// scene again (and choose every pipeline afresh).
    pub fn keys_for_edit(&self, scene: &Scene) -> Option<PipelineKeys> {
        self.edits_in_place(scene)
            .then(|| self.keys_after_edit(scene))
    }

    fn keys_after_edit(&self, scene: &Scene) -> PipelineKeys {
        let want = trace::Variant::of(scene, &self.buffers, &self.settings);
        PipelineKeys {
            raster: RasterPass::variant_of(scene, &self.buffers, &self.settings),
            trace: self.trace.variant_for_edit(want),
            driver: self.trace.uses_driver(),
            reproject: self.settings.temporal != Temporal::Off,
            accumulate: self.accumulate_kernels(scene, &self.settings),
        }
    }

    /// The pipelines [`Renderer::set_settings`]`(settings)` would draw
    /// with; `None` where it might change how rays find the scene (the
    /// driver's structures or celray's BVH), which it decides then.
    pub fn keys_for_settings(&self, settings: &RenderSettings) -> Option<PipelineKeys> {
        let raster = |s: &RenderSettings| s.mode == RenderMode::Raster;
        (settings.accel == self.settings.accel && raster(settings) == raster(&self.settings)).then(
            || PipelineKeys {
                raster: RasterPass::variant_of(&self.scene, &self.buffers, settings),
                trace: trace::Variant::of(&self.scene, &self.buffers, settings),
                reproject: settings.temporal != Temporal::Off,
                accumulate: self.accumulate_kernels(&self.scene, settings),
                ..self.pipeline_keys()
            },
        )
    }

    /// Draws with the accumulate tiles a `width` x `height` image of this
    /// scene takes ([`accumulate::accumulate_tile_px`]), whatever its own
    /// size: how a warm-up at a small size compiles a large view's tiles
    /// where no pipeline keys say which ([`warmup`]).
    pub fn use_tiles_of_size(&mut self, width: u32, height: u32) {
        let widest = max_outline_px(&self.scene);
        self.tile_px = Some(self.accumulate.tile_px(widest, width, height));
        self.tile_cache = None;
    }

    /// Draws with the pipelines of `keys` from now on (building them if
    /// needed): how a renderer made only to compile them ahead of a change
    /// draws what the changed renderer will ([`warmup`]), at a size of its
    /// own (the accumulate tiles stay those of `keys`).
    pub fn use_pipelines(&mut self, gpu: &Gpu, keys: &PipelineKeys) -> Result<(), GpuError> {
        if keys.driver != self.trace.uses_driver() {
            return Err(GpuError::Unsupported(
                "these pipelines trace through another acceleration structure".into(),
            ));
        }
        self.tile_px = Some(keys.accumulate.tile_px);
        self.tile_cache = None;
        self.raster.prepare(gpu, &self.frame, keys.raster);
        self.trace.select_variant(gpu, keys.trace)
    }

    /// Changes the camera only (no upload) and restarts accumulation; with
    /// temporal reprojection on, the next sample is blended into the last
    /// frame reprojected, and exact accumulation restarts after it.
    pub fn set_camera(&mut self, camera: crate::scene::Camera) {
        let reprojects = self.reproject.is_some()
            && self.temporal.last_view.is_some()
            && camera.width == self.scene.camera.width
            && camera.height == self.scene.camera.height;
        self.scene.camera = camera;
        self.tile_cache = None;
        if reprojects {
            self.samples = 0;
            self.temporal.moved = true;
        } else {
            self.reset();
        }
    }

    /// Applies new settings (new targets if the size changed) and restarts.
    pub fn set_settings(&mut self, gpu: &Gpu, settings: RenderSettings) -> Result<(), GpuError> {
        self.partial_gbuffer = None;
        self.tile_cache = None;
        if (settings.width, settings.height) != (self.targets.width, self.targets.height) {
            self.targets = Targets::new(gpu, settings.width, settings.height)?;
        }
        let accel_changed = settings.accel != self.settings.accel
            || (settings.mode == RenderMode::Raster) != (self.settings.mode == RenderMode::Raster);
        self.settings = settings;
        if accel_changed {
            (self.driver, self.accel_notice) =
                choose_driver(gpu, &self.scene, &self.buffers, &self.settings);
        }
        self.bind(gpu)?;
        self.reset();
        Ok(())
    }

    /// Which sample k is: the settings' schedule through the camera's aperture.
    pub fn sample_schedule(&self) -> SampleSchedule {
        self.settings.sample_schedule(&self.scene.camera)
    }

    /// The camera of sample `k`: at its shutter time, on its lens point, with
    /// its jittered and sheared projection.
    pub fn sample_camera(&self, k: u32) -> camera::SampleCamera {
        self.camera_for(&self.sample_schedule().sample(k))
    }

    /// The camera sample `k`'s tiles (`accel::screen_tiles`) are made
    /// for: its own, without its sub-pixel jitter where the lens is a
    /// pinhole, and at the shutter's opening where the camera does not
    /// move (its position at other times differs only by rounding). Each
    /// of the kernels' rays of a tile then lies within half a pixel of a
    /// ray of the tile, which every tile proof covers: each grows its
    /// tiles by `screen_tiles::TILE_PAD_PX` (2 px, for f32 rounding that a
    /// millionth of a pixel would cover). So the samples of a still camera
    /// share their tiles ([`Renderer::sample_tiles`]); with an aperture,
    /// each sample's lens point moves the eye, and its tiles are its own.
    fn tile_camera(&self, k: u32) -> camera::SampleCamera {
        let mut smp = self.sample_schedule().sample(k);
        if self.scene.camera.aperture_radius == 0.0 {
            smp.pixel_offset = glam::Vec2::splat(0.5);
        }
        if !self.scene.camera.moves() {
            smp.time = 0.0;
        }
        self.camera_for(&smp)
    }

    fn camera_for(&self, smp: &Sample) -> camera::SampleCamera {
        let s = &self.settings;
        let cam = self.scene.camera.at(smp.time);
        let depth = camera::depth_range(&cam, self.buffers.world_bounds);
        camera::sample_camera(&cam, (s.width, s.height), smp.pixel_offset, smp.lens, depth)
    }

    /// The current camera without jitter or lens offset (mid-shutter).
    fn view_matrices(&self) -> ViewMatrices {
        let s = &self.settings;
        let cam = self.scene.camera.at(0.5);
        let depth = camera::depth_range(&cam, self.buffers.world_bounds);
        let c = camera::sample_camera(
            &cam,
            (s.width, s.height),
            glam::Vec2::splat(0.5),
            glam::Vec2::ZERO,
            depth,
        );
        ViewMatrices {
            clip_from_world: c.clip_from_world,
            eye: c.eye,
            forward: c.forward,
        }
    }

    /// The reproject pass's uniforms, from the previous frame's camera.
    fn reproject_uniforms(&self, prev: &ViewMatrices) -> ReprojectUniforms {
        let cur = self.view_matrices();
        ReprojectUniforms {
            cur_clip_from_world: cur.clip_from_world.to_cols_array_2d(),
            prev_clip_from_world: prev.clip_from_world.to_cols_array_2d(),
            prev_eye: prev.eye.extend(1.0).to_array(),
            prev_forward: prev.forward.extend(0.0).to_array(),
            max_history: TEMPORAL_MAX_HISTORY,
            clip_gamma: TEMPORAL_CLIP_GAMMA,
            depth_tolerance: TEMPORAL_DEPTH_TOLERANCE,
            rejection: match self.settings.temporal {
                Temporal::Blend => TEMPORAL_REJECT_NONE,
                Temporal::Off | Temporal::Reproject => TEMPORAL_REJECT_CLIP,
            },
        }
    }

    /// Sample `k`'s level of detail for each of the scene's draws
    /// ([`SceneBuffers::draws`]) in the raster pass: an index into the
    /// draw's levels, 0 the finest ([`raster::draw_levels`]). Empty outside
    /// raster mode, where the pass draws only meshes, which have one level.
    pub fn raster_levels(&self, k: u32) -> Vec<usize> {
        self.raster_draws(k).levels
    }

    /// What the raster pass draws for sample `k`: each draw's level
    /// ([`Renderer::raster_levels`]) and its distance from the sample's
    /// eye, by which the draws are made front to back
    /// ([`raster::draw_distances`]).
    pub fn raster_draws(&self, k: u32) -> raster::RasterDraws {
        let smp = self.sample_schedule().sample(k);
        let camera = self.camera_for(&smp);
        let time = self.buffers.has_motion.then_some(smp.time);
        let levels = if self.settings.mode == RenderMode::Raster {
            let view = raster::LodView::new(
                &self.scene.camera.at(smp.time),
                &camera,
                (self.settings.width, self.settings.height),
            );
            raster::draw_levels(&self.buffers, &self.scene, &view, time)
        } else {
            Vec::new()
        };
        let mode = self.primary_mode();
        raster::RasterDraws {
            mode,
            levels,
            distances: raster::draw_distances(&self.buffers, &self.scene, mode, camera.eye, time),
        }
    }

    /// The raster pass's draw calls for sample `k`, in order
    /// ([`raster::RasterDraws::sequence`]).
    pub fn raster_sequence(&self, k: u32) -> Vec<(usize, std::ops::Range<u32>, bool)> {
        self.raster_draws(k).sequence(&self.buffers)
    }

    /// How far the kernels start secondary rays off a surface: 1e-4 of
    /// the scene's bounding radius.
    fn ray_epsilon(&self) -> f32 {
        let (lo, hi) = self.buffers.world_bounds;
        ((hi - lo).length() * 0.5).max(1e-3) * 1e-4
    }

    /// The uniforms of sample `k`.
    fn frame_uniforms(&self, k: u32) -> FrameUniforms {
        let s = &self.settings;
        let smp = self.sample_schedule().sample(k);
        let offset = smp.pixel_offset;
        let sc = self.camera_for(&smp);
        // Inverted in f64: the projection's near/far ratio is large.
        let world_from_clip = sc.clip_from_world.as_dmat4().inverse().as_mat4();
        let max_outline = max_outline_px(&self.scene);
        FrameUniforms {
            clip_from_world: sc.clip_from_world.to_cols_array_2d(),
            eye_in_world: sc.eye.extend(1.0).to_array(),
            view_forward: sc.forward.extend(0.0).to_array(),
            ambient: self.scene.ambient.extend(0.0).to_array(),
            background: self.scene.background.extend(1.0).to_array(),
            size_px: [s.width, s.height],
            light_count: self.buffers.light_count,
            sample_index: k,
            jitter_px: (offset - glam::Vec2::splat(0.5)).to_array(),
            max_outline_px: max_outline,
            seed: smp.seed,
            world_from_clip: world_from_clip.to_cols_array_2d(),
            mode: self.primary_mode().to_gpu(),
            max_bounces: s.max_bounces,
            ray_epsilon: self.ray_epsilon(),
            // Set by render_sample, which knows whether the trace pass
            // reads its tiles.
            trace_accumulates: 0,
            gbuffer_only: 0,
            _pad1: 0,
            _pad2: 0,
            _pad3: 0,
        }
    }

    /// Sample `k`'s primary-ray tiles (`accel::screen_tiles`) for primary
    /// mode `mode`, as the trace pass reads them: the records (hybrid
    /// mode's primary rays skip the meshes, which it rasterizes), then one
    /// word per tile: in hybrid mode `TILE_MESH_MAY_SHOW` where a mesh may
    /// show (never in raytrace mode, where it is not read), and
    /// `TILE_TRACE_ACCUMULATES` where no outline can reach the tile (every
    /// tile without outlines 1 px or wider), whose pixels the trace pass
    /// adds to the accumulator itself, and `TILE_GBUFFER_SKIPS` as on a
    /// still frame (a moving frame has none).
    pub fn primary_tiles(&self, k: u32, mode: RenderMode) -> Vec<u32> {
        let kernels = self.accumulate_kernels(&self.scene, &self.settings);
        let camera = self.tile_camera(k);
        let made = self.make_tiles(&camera, mode, kernels.tile_px, kernels.outlines, true, true);
        made.tiles.unwrap_or_default()
    }

    /// The primary-ray tiles of the sample whose projection is
    /// `clip_from_world` ([`Renderer::primary_tiles`]), given that
    /// sample's outline source tiles of `tile_px` on a side (`None`: no
    /// outline reaches other pixels). On a `still` frame (no reproject pass
    /// reads the whole G-buffer) the tiles no pass reads skip their
    /// G-buffer stores ([`flag_gbuffer_skips`]); also returns whether some
    /// tile does.
    fn tiles_seen_by(
        &self,
        clip_from_world: glam::Mat4,
        mode: RenderMode,
        sources: Option<&[u32]>,
        tile_px: u32,
        still: bool,
    ) -> (Vec<u32>, bool) {
        let accel = &self.buffers.accel;
        let hybrid = mode == RenderMode::Hybrid;
        let mesh = |i: usize| accel.shapes[accel.instances[i].2 as usize].kind == SHAPE_MESH;
        let size = (self.settings.width, self.settings.height);
        let mut tiles = crate::accel::screen_tiles::primary_tiles(
            &accel.footprints,
            |i| !hybrid || !mesh(i),
            clip_from_world,
            size,
            TRACE_WORKGROUP,
        );
        let count = tiles.len() / crate::gpu::twins::PRIMARY_TILE_WORDS as usize;
        if hybrid {
            let meshes = crate::accel::screen_tiles::reached_tiles(
                &accel.footprints,
                mesh,
                clip_from_world,
                size,
                TRACE_WORKGROUP,
                0,
            );
            tiles.extend(meshes.iter().map(|&m| m * TILE_MESH_MAY_SHOW));
        } else {
            tiles.resize(tiles.len() + count, 0);
        }
        let words = crate::gpu::twins::PRIMARY_TILE_WORDS as usize;
        let (records, flag_words) = tiles.split_at_mut(count * words);
        for (record, word) in records.chunks_exact(words).zip(flag_words.iter_mut()) {
            *word |= crate::accel::screen_tiles::record_summary(record) << TILE_RECORD_SHIFT;
        }
        self.flag_unshadowed(flag_words, clip_from_world);
        if !self.trace_may_accumulate {
            return (tiles, false);
        }
        // An accumulate tile holds whole trace tiles (8 or 16 px against 8).
        debug_assert!(tile_px.is_multiple_of(TRACE_WORKGROUP));
        let trace_x = size.0.div_ceil(TRACE_WORKGROUP) as usize;
        let source_x = size.0.div_ceil(tile_px) as usize;
        let per = (tile_px / TRACE_WORKGROUP) as usize;
        let flags = tiles.len() - count;
        for (t, word) in tiles[flags..].iter_mut().enumerate() {
            let (x, y) = (t % trace_x, t / trace_x);
            if sources.is_none_or(|s| s[(y / per) * source_x + x / per] == 0) {
                *word |= TILE_TRACE_ACCUMULATES;
            }
        }
        let skips =
            still && flag_gbuffer_skips(&mut tiles, &self.scene, &self.settings, sources, tile_px);
        (tiles, skips)
    }

    /// Sets [`TILE_UNSHADOWED`] in the tiles' flag words (one per trace
    /// tile, their record summaries in place) where every primary hit is
    /// on one static quad or disk whose shadow rays there meet nothing,
    /// for the sample whose projection is `clip_from_world`: where exactly
    /// one light casts shadows, a directional one with a cull grid (its
    /// [`crate::accel::shadow_cull::CulledRegions`], built with the cull
    /// data). The planes' regions are proven in groups of 4 x 4 tiles,
    /// about 900 a 1280 x 720 sample, the first [`UNSHADOWED_PLANES`]
    /// planes only.
    fn flag_unshadowed(&self, flag_words: &mut [u32], clip_from_world: glam::Mat4) {
        let Some(regions) = &self.buffers.sun else {
            return;
        };
        let epsilon = f64::from(self.ray_epsilon());
        let size = (self.settings.width, self.settings.height);
        let planes = self.buffers.accel.exact_planes.iter().filter(|p| !p.face);
        // A summary holds instance indices below TILE_RECORD_READ - 1.
        let summarized = |p: &&crate::accel::screen_tiles::ExactPlane| {
            (p.instance as u32) < crate::gpu::twins::TILE_RECORD_READ - 1
        };
        for plane in planes.filter(summarized).take(UNSHADOWED_PLANES) {
            let proven = crate::accel::screen_tiles::plane_region_tiles(
                plane,
                clip_from_world,
                size,
                TRACE_WORKGROUP,
                4,
                epsilon,
                |points| regions.all_culled(points),
            );
            let alone = (plane.instance as u32 + 1) << TILE_RECORD_SHIFT;
            for (word, proven) in flag_words.iter_mut().zip(proven) {
                let summary = *word & !((1 << TILE_RECORD_SHIFT) - 1);
                if proven && summary == alone && *word & TILE_MESH_MAY_SHOW == 0 {
                    *word |= TILE_UNSHADOWED;
                }
            }
        }
    }

    /// Per accumulate tile of `tile_px`, 1 where a pixel of it may take an
    /// outline in the sample whose projection is `clip_from_world` (view
    /// direction `forward`) with primary mode `mode`: an
    /// instance whose outline reaches other pixels may show within the
    /// outline radius of it (`accel::screen_tiles::reached_tiles`), unless
    /// the CPU proves the tile and its halo the smooth inside of one sphere
    /// (traced primary hits only: `screen_tiles::smooth_sphere_tiles`) or
    /// of one quad or disk (disks traced only:
    /// `screen_tiles::smooth_plane_tiles`), where the outline marks would
    /// prove the same texel by texel;
    /// 1 everywhere in scenes of more than `MAX_TILED_INSTANCES` instances,
    /// where projecting them all for each sample would cost more than the
    /// reads it saves.
    fn source_tiles_seen_by(
        &self,
        clip_from_world: glam::Mat4,
        forward: glam::Vec3,
        tile_px: u32,
        mode: RenderMode,
    ) -> Vec<u32> {
        use crate::accel::screen_tiles::{self, SmoothSteps};
        let accel = &self.buffers.accel;
        let size = (self.settings.width, self.settings.height);
        if accel.world_bounds.len() > screen_tiles::MAX_TILED_INSTANCES {
            let tiles = size.0.div_ceil(tile_px) * size.1.div_ceil(tile_px);
            return vec![1; tiles as usize];
        }
        let scene = &self.scene;
        let order = &self.buffers.instance_order;
        let reach = max_outline_px(scene).floor() as u32;
        let mut tiles = screen_tiles::reached_tiles(
            &accel.footprints,
            |k| scene.materials[scene.instances[order[k]].material].outline_width_px >= 1.0,
            clip_from_world,
            size,
            tile_px,
            reach,
        );
        if !self.smooth_tiles {
            return tiles;
        }
        let steps = SmoothSteps::for_radius(reach);
        let mut clear = |smooth: Vec<bool>| {
            for (t, smooth) in tiles.iter_mut().zip(smooth) {
                if smooth {
                    *t = 0;
                }
            }
        };
        // The raster pass draws spheres and disks as tessellations, whose
        // normals and depths (spheres) and rims (disks) the proofs do not
        // bound; a quad is two triangles over the same points.
        let raster = mode == RenderMode::Raster;
        if !raster {
            clear(screen_tiles::smooth_sphere_tiles(
                &accel.footprints,
                &accel.exact_spheres,
                forward,
                clip_from_world,
                size,
                tile_px,
                reach,
                steps,
            ));
        }
        let planes: Vec<_> = (accel.exact_planes.iter())
            .filter(|p| !(raster && p.disk))
            .copied()
            .collect();
        clear(screen_tiles::smooth_plane_tiles(
            &accel.footprints,
            &planes,
            forward,
            clip_from_world,
            size,
            tile_px,
            reach,
            steps,
        ));
        tiles
    }

    /// Sample `k`'s outline source tiles (where `outlines`) and primary
    /// tiles (where `reads_tiles`; `still`: no reproject pass reads the
    /// whole G-buffer) for its tile camera ([`Renderer::tile_camera`]),
    /// with what they are made for; `None` for the tiles where the last
    /// sample's were made for the same (a still camera's samples, on a
    /// pinhole lens): the passes hold them already (`tile_cache`). On lavapipe making
    /// them took 1.3-2.7 ms of a csg_textbook sample's CPU time
    /// (docs/performance-history.md, fortieth session).
    #[allow(clippy::too_many_arguments)]
    fn sample_tiles(
        &self,
        k: u32,
        mode: RenderMode,
        tile_px: u32,
        outlines: bool,
        reads_tiles: bool,
        still: bool,
    ) -> (TileKey, Option<SampleTiles>) {
        let camera = self.tile_camera(k);
        let key = TileKey {
            clip_from_world: camera.clip_from_world.to_cols_array(),
            mode,
            tile_px,
            outlines,
            reads_tiles,
            still,
        };
        if self.tile_cache.is_some_and(|(last, _)| last == key) {
            return (key, None);
        }
        let made = self.make_tiles(&camera, mode, tile_px, outlines, reads_tiles, still);
        (key, Some(made))
    }

    /// The outline source tiles (where `outlines`) and primary tiles
    /// (where `reads_tiles`) of a sample seen by `camera`
    /// ([`Renderer::sample_tiles`] without its cache).
    fn make_tiles(
        &self,
        camera: &camera::SampleCamera,
        mode: RenderMode,
        tile_px: u32,
        outlines: bool,
        reads_tiles: bool,
        still: bool,
    ) -> SampleTiles {
        let (clip_from_world, forward) = (camera.clip_from_world, camera.forward);
        let sources =
            outlines.then(|| self.source_tiles_seen_by(clip_from_world, forward, tile_px, mode));
        let (mut tiles, mut skips) = (None, false);
        if reads_tiles {
            let words;
            (words, skips) =
                self.tiles_seen_by(clip_from_world, mode, sources.as_deref(), tile_px, still);
            tiles = Some(words);
        }
        SampleTiles {
            sources,
            tiles,
            skips,
        }
    }

    /// Renders one more sample into the accumulator (one dispatch per pass,
    /// one sample per pixel: see the loop limit in STACK-NOTES.md), timing
    /// its passes when [`Renderer::enable_pass_timing`] was called and the
    /// last timed sample has been read back.
    pub fn render_sample(&mut self, gpu: &Gpu) -> Result<(), GpuError> {
        // A moving frame (temporal on, camera changed since the last frame)
        // takes the next index of the sample schedule, so jitter, lens and
        // shutter time keep converging through the history.
        if self.reproject.is_some() && self.temporal.moved {
            // A moving frame: its reproject pass's history is the last
            // sample's G-buffer, every pixel of it.
            self.complete_gbuffer(gpu);
        }
        let moving = match (&self.reproject, self.temporal.last_view) {
            (Some(pass), Some(prev)) if self.temporal.moved => Some((pass, prev)),
            _ => None,
        };
        let k = if moving.is_some() {
            self.temporal.next_k % self.settings.spp.max(1)
        } else {
            self.samples
        };
        let mut uniforms = self.frame_uniforms(k);
        let draws = self.raster_draws(k);
        let mode = self.primary_mode();
        // An outline under 1 px reaches no other pixel (search radius 0).
        let kernels = self.accumulate_kernels(&self.scene, &self.settings);
        self.accumulate.note_run(kernels);
        let (outlines, tile_px) = (kernels.outlines, kernels.tile_px);
        // Where the trace pass reads tiles, it adds the colour of those no
        // outline reaches to the accumulator itself (every tile without
        // outlines): the accumulate pass would only copy it there.
        let reads_tiles = mode != RenderMode::Raster && self.trace.reads_tiles();
        let trace_accumulates = reads_tiles && self.trace_may_accumulate;
        // A moving frame's reproject pass reads the whole G-buffer.
        let still = moving.is_none();
        let (key, made) = self.sample_tiles(k, mode, tile_px, outlines, reads_tiles, still);
        if let Some(SampleTiles {
            sources,
            tiles,
            skips,
        }) = made
        {
            if let Some(tiles) = tiles {
                self.trace.write_tiles(gpu, tiles);
            }
            if let Some(sources) = sources {
                self.accumulate.write_source_tiles(gpu, sources);
            }
            self.tile_cache = Some((key, skips));
        }
        let skips = self.tile_cache.is_some_and(|(_, skips)| skips);
        uniforms.trace_accumulates = u32::from(trace_accumulates);
        self.partial_gbuffer = skips.then_some(uniforms);
        if let Some((pass, prev)) = &moving {
            pass.write_uniforms(gpu, &self.reproject_uniforms(prev));
        }
        let mut motion_time = None;
        if self.buffers.has_motion {
            let time = self.sample_schedule().sample(k).time;
            self.buffers.write_instances_at(gpu, &self.scene, time);
            motion_time = Some(time);
        }
        gpu.queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(&uniforms));
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("sample"),
            });
        let background = [
            uniforms.background[0],
            uniforms.background[1],
            uniforms.background[2],
        ];
        let timed = self.timer.as_mut().is_some_and(|t| {
            t.last_timed = t.on && t.timer.begin();
            t.last_timed
        });
        let mut timer = self.timer.as_mut().filter(|_| timed);
        let traced = mode != RenderMode::Raster;
        if let Some((pass, _)) = &moving {
            pass.encode_snapshot(&mut encoder, &self.targets, traced);
        }
        // In raytrace mode (and hybrid without meshes, which runs as
        // raytrace) nothing reads the raster targets: no pass at all.
        if mode != RenderMode::Raytrace {
            self.raster.encode(
                &mut encoder,
                &self.targets,
                &self.buffers,
                background,
                &draws,
                timer.as_mut().and_then(|t| t.timer.render_writes(t.raster)),
            );
        }
        if let (true, Some(time), Some(driver)) = (traced, motion_time, self.driver.as_mut()) {
            // The driver's top level holds sample k's transforms: rebuilt here.
            driver.encode_motion(&mut encoder, &self.scene, time);
        }
        if traced {
            self.trace.encode(
                &mut encoder,
                &self.targets,
                timer.as_mut().and_then(|t| t.timer.compute_writes(t.trace)),
            );
            // The accumulate pass reads the trace pass's buffers; the
            // reproject pass reads textures.
            if moving.is_some() {
                let t = &self.targets.traced;
                (self.targets.traced_output).encode_copy(&mut encoder, &t.normal_depth, &t.id);
            }
        }
        if outlines {
            self.accumulate.encode_tiles(
                &mut encoder,
                &self.targets,
                kernels.gbuffer,
                tile_px,
                timer
                    .as_mut()
                    .and_then(|t| t.timer.compute_writes(t.outline_tiles)),
            );
        }
        // Without outlines, the trace pass accumulated every pixel.
        if outlines || !trace_accumulates {
            self.accumulate.encode(
                &mut encoder,
                &self.targets,
                kernels,
                trace_accumulates,
                timer
                    .as_mut()
                    .and_then(|t| t.timer.compute_writes(t.accumulate)),
            );
        }
        if let Some((pass, _)) = &moving {
            pass.encode(
                &mut encoder,
                &self.targets,
                traced,
                timer
                    .as_mut()
                    .and_then(|t| t.timer.compute_writes(t.reproject)),
            );
        }
        if let Some(t) = &mut timer {
            t.timer.finish(&mut encoder);
        }
        gpu.queue.submit([encoder.finish()]);
        if let Some(t) = &mut self.timer {
            t.timer.after_submit();
        }
        self.temporal.last_moved = moving.is_some();
        if moving.is_some() {
            self.temporal.moved = false;
            self.temporal.next_k = (k + 1) % self.settings.spp.max(1);
        } else {
            self.samples += 1;
        }
        self.temporal.last_view = Some(self.view_matrices());
        gpu.take_errors()
    }

    /// Starts timing each pass on the GPU (where the adapter has timestamp
    /// queries); returns whether it can.
    pub fn enable_pass_timing(&mut self, gpu: &Gpu) -> bool {
        if self.timer.is_none() {
            self.timer = SampleTimer::new(gpu);
        }
        self.timer.is_some()
    }

    /// Whether the next samples are timed, where pass timing is enabled (on
    /// by default; the window times one frame in a few,
    /// `app::timing::FrameTimer`).
    pub fn time_samples(&mut self, on: bool) {
        if let Some(t) = &mut self.timer {
            t.on = on;
        }
    }

    /// GPU milliseconds per pass of the last sample, in the order of
    /// [`PASS_NAMES`] (blocks until it is done). Empty without timing, or
    /// when that sample was not timed because an earlier one's times had
    /// not been read yet: call this after every timed sample.
    pub fn pass_times(&mut self, gpu: &Gpu) -> Result<Vec<(&'static str, f64)>, GpuError> {
        match &mut self.timer {
            Some(t) if t.last_timed => t.timer.wait(gpu),
            _ => Ok(Vec::new()),
        }
    }

    /// The pass times of a timed sample whose read-back has finished since
    /// the last call, without waiting (call after a device poll).
    pub fn collect_pass_times(&mut self) -> Option<&[(&'static str, f64)]> {
        self.timer.as_mut().and_then(|t| t.timer.collect())
    }

    /// Whether the last sample was a moving frame (blended into the
    /// reprojected history rather than accumulated exactly).
    pub fn last_frame_moved(&self) -> bool {
        self.temporal.last_moved
    }

    /// Motion vectors of the last moving frame, in pixels per pixel (row-major,
    /// top row first): where each pixel's surface point is now minus where it
    /// was in the frame before. None unless temporal reprojection is on.
    pub fn read_motion_vectors(&self, gpu: &Gpu) -> Result<Option<Vec<[f32; 2]>>, GpuError> {
        let Some(buffer) = self.reproject.as_ref().and_then(|p| p.motion_buffer()) else {
            return Ok(None);
        };
        let bytes = readback::copy_and_read(gpu, buffer, buffer.size(), "motion vector readback")?;
        Ok(Some(bytemuck::cast_slice(&bytes).to_vec()))
    }

    /// Renders samples until `settings.spp` are accumulated, calling
    /// `progress(done, total)` after each.
    pub fn render_to_convergence(
        &mut self,
        gpu: &Gpu,
        mut progress: impl FnMut(u32, u32),
    ) -> Result<(), GpuError> {
        while !self.converged() {
            self.render_sample(gpu)?;
            progress(self.samples, self.settings.spp);
        }
        gpu.wait_idle()
    }

    /// Records the resolve of the current average (tone mapped, encoded
    /// for `target`'s format) into `target`, which must be a 2D texture of
    /// the image's size with `RENDER_ATTACHMENT` usage. The first call for
    /// a format builds its pass; the renderer keeps every pass bound to its
    /// current accumulator and settings, so nothing is to be redone after
    /// [`Renderer::set_settings`] or any other change.
    pub fn resolve_into(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::Texture,
    ) -> Result<(), GpuError> {
        self.resolve_into_as(gpu, encoder, target, target.format())
    }

    /// [`Renderer::resolve_into`] through a view of `target` in
    /// `view_format`, one of the view formats `target` was created with.
    /// Resolving a non-sRGB texture through its sRGB twin lets the target
    /// encode as it stores rather than the shader: on the CPU driver that
    /// saves about 2 ms of a 1280x720 resolve's 8 (docs/performance-history.md),
    /// and the bytes are those a capture gets.
    pub fn resolve_into_as(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::Texture,
        view_format: wgpu::TextureFormat,
    ) -> Result<(), GpuError> {
        let size = (target.width(), target.height());
        if size != (self.targets.width, self.targets.height) {
            return Err(GpuError::Unsupported(format!(
                "resolve into a {}x{} texture from a {}x{} image (the sizes must match)",
                size.0, size.1, self.targets.width, self.targets.height
            )));
        }
        let index = match self.resolves.iter().position(|p| p.format() == view_format) {
            Some(i) => i,
            None => {
                let mut pass = ResolvePass::new(gpu, view_format)?;
                pass.prepare(gpu, &self.settings, &self.targets)?;
                self.resolves.push(pass);
                self.resolves.len() - 1
            }
        };
        let view = target.create_view(&wgpu::TextureViewDescriptor {
            format: Some(view_format),
            ..Default::default()
        });
        self.resolves[index].encode(encoder, &view);
        Ok(())
    }

    /// The resolved image as sRGB-encoded RGBA8, row-major, top row first.
    pub fn read_srgb8(&self, gpu: &Gpu) -> Result<Vec<u8>, GpuError> {
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("capture resolve"),
            });
        let view = self.targets.capture.create_view(&Default::default());
        let capture = self
            .resolves
            .iter()
            .find(|p| p.format() == targets::CAPTURE_FORMAT)
            .ok_or_else(|| GpuError::Unsupported("no capture resolve pass".into()))?;
        capture.encode(&mut encoder, &view);
        gpu.queue.submit([encoder.finish()]);
        let bytes = readback::read_texture(gpu, &self.targets.capture, 4)?;
        gpu.take_errors()?;
        Ok(bytes)
    }

    /// The accumulated average in linear RGBA f32 (before tone mapping).
    pub fn read_linear(&self, gpu: &Gpu) -> Result<Vec<f32>, GpuError> {
        Ok(self
            .read_accumulator(gpu)?
            .iter()
            .flat_map(|s| {
                let n = s[3].max(1.0);
                [s[0] / n, s[1] / n, s[2] / n, 1.0]
            })
            .collect())
    }

    /// The accumulator as stored: per pixel the colour sum (rgb) and the
    /// number of samples it holds (w; after a moving frame, the count the
    /// reprojected history holds).
    pub fn read_accumulator(&self, gpu: &Gpu) -> Result<Vec<[f32; 4]>, GpuError> {
        let accum = &self.targets.accum;
        let bytes = readback::copy_and_read(gpu, accum, accum.size(), "accumulation readback")?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }

    /// Pixels (summed over samples) whose ray traversal ran out of its step
    /// budget and were painted magenta: 0 unless a scene is too deep.
    pub fn overflow_pixels(&self, gpu: &Gpu) -> Result<u32, GpuError> {
        self.trace.overflow_pixels(gpu)
    }

    /// The primary tiles the trace kernel read in the last sample, where
    /// it reads them (`accel::screen_tiles`; else every tile walks). For
    /// tests.
    pub fn read_primary_tiles(&self, gpu: &Gpu) -> Result<Vec<u32>, GpuError> {
        self.trace.read_tiles(gpu)
    }

    /// The G-buffer's id target: 0 for background, else GPU instance + 1
    /// (see [`SceneBuffers::instance_order`]), of the last sample (after a
    /// change, the texels that sample left unstored hold older values until
    /// the next one). For tests (picking is [`Renderer::pick`], on the CPU).
    /// Where raster mode keeps the ids in the colour's alpha
    /// ([`raster::ids_in_color`]), read from there.
    pub fn read_ids(&self, gpu: &Gpu) -> Result<Vec<u32>, GpuError> {
        if self.raster.variant().ids_in_color() {
            // The ids are the colour's alpha, a half float per texel.
            let bytes = readback::read_texture(gpu, &self.targets.raster.color, 8)?;
            return Ok(bytes
                .chunks_exact(8)
                .map(|t| half::f16::from_le_bytes([t[6], t[7]]).to_f32() as u32)
                .collect());
        }
        let bytes = readback::read_texture(gpu, self.gbuffer(gpu).1, 4)?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }

    /// The G-buffer's normal (xyz, world space) and view depth (w) per
    /// pixel, as the accumulate pass's outline search reads them. Defined
    /// only where the id ([`Renderer::read_ids`]) is not 0: the raster pass
    /// does not clear it. For tests.
    pub fn read_normal_depth(&self, gpu: &Gpu) -> Result<Vec<[f32; 4]>, GpuError> {
        let bytes = readback::read_texture(gpu, self.gbuffer(gpu).0, 16)?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }

    /// Per accumulate tile ([`Renderer::outline_tile_px`] on a side, row by
    /// row), whether the last sample's outline search ran there (1) or was
    /// skipped (0). For tests.
    pub fn read_outline_tile_marks(&self, gpu: &Gpu) -> Result<Vec<u32>, GpuError> {
        let marks = self.read_outline_tile_words(gpu)?;
        Ok(marks
            .into_iter()
            .map(|m| u32::from(m == OUTLINE_MARK_SEARCH))
            .collect())
    }

    /// The outline marks as the accumulate pass read them
    /// (`OUTLINE_MARK_SEARCH`, `OUTLINE_MARK_TRACED` where the trace pass
    /// accumulated the tile, or 0), per tile as
    /// [`Renderer::read_outline_tile_marks`]. For tests.
    pub fn read_outline_tile_words(&self, gpu: &Gpu) -> Result<Vec<u32>, GpuError> {
        self.accumulate
            .read_tile_marks(gpu, &self.targets, self.outline_tile_px())
    }

    /// The last sample's source tiles, as the CPU made them for the
    /// outline marks (one word per tile of [`Renderer::outline_tile_px`],
    /// row by row: 0 where no outline can reach the tile, or where the CPU
    /// proves it smooth; [`Gpu::set_smooth_tiles`]). For tests.
    pub fn source_tiles(&self) -> &[u32] {
        self.accumulate.source_tiles()
    }

    /// The edge (pixels) of the accumulate pass's tiles for this scene's
    /// outlines and image size ([`accumulate::accumulate_tile_px`]).
    pub fn outline_tile_px(&self) -> u32 {
        self.accumulate_kernels(&self.scene, &self.settings).tile_px
    }

    /// Whether the outline search runs over the list of marked tiles (one
    /// indirect dispatch), else over every tile ([`Gpu::set_outline_tile_list`],
    /// or more tiles than one dispatch may count). For tests.
    pub fn outline_search_listed(&self) -> bool {
        self.accumulate.listed(self.outline_tile_px())
    }

    /// How this renderer's samples find primary visibility: the settings'
    /// mode, except that hybrid mode with no triangle mesh to rasterize
    /// traces everything as raytrace mode does (the same rays, the same
    /// image) and skips a raster pass that would only clear its targets.
    fn primary_mode(&self) -> RenderMode {
        match self.settings.mode {
            RenderMode::Hybrid
                if !self
                    .buffers
                    .draws
                    .iter()
                    .any(|d| d.drawn_in(RenderMode::Hybrid)) =>
            {
                RenderMode::Raytrace
            }
            mode => mode,
        }
    }

    /// Stores the normal, depth and id that the last sample's trace pass
    /// left unstored (`TILE_GBUFFER_SKIPS`), for a reader of the whole
    /// G-buffer (a moving frame's reproject pass, the read-backs): the
    /// pass again, over the same tiles with the same uniforms but
    /// `gbuffer_only`, which stores the primary hits of the tiles the
    /// sample left unstored, passes over the others, and shades and adds
    /// nothing. Submitted at once, before the next sample writes
    /// its uniforms and tiles.
    fn complete_gbuffer(&self, gpu: &Gpu) {
        let Some(uniforms) = self.partial_gbuffer else {
            return;
        };
        let only = FrameUniforms {
            gbuffer_only: 1,
            ..uniforms
        };
        gpu.queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(&only));
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("G-buffer completion"),
            });
        self.trace.encode(&mut encoder, &self.targets, None);
        gpu.queue.submit([encoder.finish()]);
        gpu.queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(&uniforms));
    }

    /// The normal + depth and id textures of the G-buffer the accumulate
    /// pass read in the last sample: in hybrid and raytrace mode the trace
    /// pass's buffers, first copied into the traced textures (the samples
    /// skip that copy unless a reproject pass follows).
    fn gbuffer(&self, gpu: &Gpu) -> (&wgpu::Texture, &wgpu::Texture) {
        if self.settings.mode == RenderMode::Raster {
            let g = &self.targets.raster;
            return (&g.normal_depth, &g.id);
        }
        self.complete_gbuffer(gpu);
        let t = &self.targets.traced;
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("traced G-buffer copy"),
            });
        (self.targets.traced_output).encode_copy(&mut encoder, &t.normal_depth, &t.id);
        gpu.queue.submit([encoder.finish()]);
        (&t.normal_depth, &t.id)
    }
}
