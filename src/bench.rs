//! `celray bench`: frame times and ray throughput on whatever adapter is
//! chosen, on the scenes other renderers were timed on
//! (../shared/bench/anchor-scenes.md). Timings live here, never in tests.

mod ab;
mod accel;
mod csg;
mod export;
mod floor;
mod report;

use report::{md, Report};

use std::path::PathBuf;
use std::time::Instant;

use glam::{Mat4, Vec3};

use celray::gpu::shader::ShaderOverrides;
use celray::gpu::timer::{GpuTimer, Span};
use celray::gpu::twins::GpuRay;
use celray::gpu::Gpu;
use celray::render::ray_batch::RayBatch;
use celray::render::{AccelChoice, RenderMode, RenderSettings, Renderer};
use celray::scene::{Instance, Light, Scene};

#[derive(Debug, Clone, clap::Args)]
pub struct BenchArgs {
    /// Which cases: floor, raster, rays, effects (with temporal), csg, accel
    /// (driver ray queries vs the software BVH), temporal, all, or scene
    /// (one case, `scene`: frames of the --scene file in --mode).
    #[arg(default_value = "all")]
    pub suite: String,
    /// With suite `scene`: the scene file whose frames are timed.
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
    /// With suite `scene`: how primary visibility is found.
    #[arg(long, value_enum, default_value_t = RenderMode::Hybrid)]
    pub mode: RenderMode,
    /// Frames timed per case (after 3 warm-up frames).
    #[arg(long, default_value_t = 20)]
    pub frames: u32,
    /// Image width.
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Folder holding FlightHelmet/FlightHelmet.gltf (the shared test models).
    #[arg(long, default_value = "../shared/models")]
    pub models: PathBuf,
    /// One JSON object per line per case (case, ms, mrays_per_s,
    /// floor_ratio, kernels, driver) instead of Markdown tables.
    #[arg(long)]
    pub json: bool,
    /// With suite `rays` or `all`: also write helmet_rays' world-space
    /// triangles, its rays and celray's closest-hit distances to FILE (a new
    /// file), for an outside ray tracer to time the same rays
    /// (tools/embree-compare).
    #[arg(long, value_name = "FILE")]
    pub export_rays: Option<PathBuf>,
    /// What `kernels` gives per pass over the timed frames: the mean, or
    /// the fastest frame's GPU ms (min), which a shared or busy machine
    /// disturbs far less (docs/performance.md).
    #[arg(long, value_enum, default_value_t = PassStat::Mean)]
    pub pass_stat: PassStat,
    /// Read shader files from DIR (by their path under `shaders/`), the
    /// built-in copy for those it lacks: to time a kernel change without
    /// rebuilding.
    #[arg(long, value_name = "DIR")]
    pub shaders: Option<PathBuf>,
    /// With suite `scene`: also time the scene with DIR's shader files (B,
    /// read as --shaders reads them) against the shaders in use (A),
    /// alternating frame by frame in one process, and print per pass the
    /// fastest frame of each and the median ratio B / A over the
    /// `--frames` pairs: a busy machine disturbs both alike. With suite
    /// `rays`: the same for the ray cases' batches (the ray-batch kernel),
    /// dispatch by dispatch.
    #[arg(long, value_name = "DIR")]
    pub compare_shaders: Option<PathBuf>,
    /// Read every scene table from its storage buffer, none from the
    /// uniform copies the small ones have otherwise (gpu::uniform_tables):
    /// the same images, to time what the copies save.
    #[arg(long)]
    pub storage_tables: bool,
    /// The global `--accel` (set by main): what the frame cases walk.
    #[arg(skip)]
    pub accel: celray::render::AccelChoice,
}

/// How each pass's GPU time is summed up over the timed frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum PassStat {
    #[default]
    Mean,
    Min,
}

/// Wall milliseconds per frame (mean, median) and GPU ms per pass.
struct FrameStats {
    mean: f64,
    median: f64,
    passes: Vec<(&'static str, f64)>,
}

/// One renderer timed frame by frame: each frame one sample (all passes)
/// plus a resolve into an 8-bit target, waited for: what a window waits
/// per frame.
struct TimedRenderer {
    renderer: Renderer,
    target: wgpu::Texture,
    resolve_timer: Option<(GpuTimer, [Span; 1])>,
}

impl TimedRenderer {
    fn new(gpu: &Gpu, scene: Scene, mode: RenderMode, args: &BenchArgs) -> anyhow::Result<Self> {
        let settings = RenderSettings {
            width: args.width,
            height: args.height,
            spp: 1 << 20,
            mode,
            accel: args.accel,
            ..RenderSettings::default()
        };
        let mut renderer = Renderer::new(gpu, scene, settings)?;
        let target = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("bench target"),
            size: wgpu::Extent3d {
                width: args.width,
                height: args.height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8UnormSrgb,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        renderer.enable_pass_timing(gpu);
        // The resolve is recorded outside the renderer's sample, as a window
        // records it: timed as a pass of its own where the device stamps
        // inside encoders.
        let resolve_timer = GpuTimer::new(gpu, "bench resolve", ["resolve"])
            .filter(|(timer, _)| timer.stamps_inside_encoders());
        Ok(TimedRenderer {
            renderer,
            target,
            resolve_timer,
        })
    }

    /// One frame: its wall milliseconds and its GPU milliseconds per pass.
    fn frame(&mut self, gpu: &Gpu) -> anyhow::Result<(f64, Vec<(&'static str, f64)>)> {
        let start = Instant::now();
        self.renderer.render_sample(gpu)?;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        if let Some((timer, [span])) = self.resolve_timer.as_mut() {
            timer.begin();
            timer.stamp_begin(&mut encoder, *span);
        }
        self.renderer
            .resolve_into(gpu, &mut encoder, &self.target)?;
        if let Some((timer, [span])) = self.resolve_timer.as_mut() {
            timer.stamp_end(&mut encoder, *span);
            timer.finish(&mut encoder);
        }
        gpu.queue.submit([encoder.finish()]);
        if let Some((timer, _)) = self.resolve_timer.as_mut() {
            timer.after_submit();
        }
        gpu.wait_idle()?;
        let wall_ms = start.elapsed().as_secs_f64() * 1e3;
        // Read every sample's pass times, warm-up ones too: a sample is
        // timed only once the one before it has been read.
        let mut pass_times = self.renderer.pass_times(gpu)?;
        if let Some((timer, _)) = self.resolve_timer.as_mut() {
            pass_times.extend(timer.wait(gpu)?);
        }
        Ok((wall_ms, pass_times))
    }
}

/// Frames before the timed ones: the first builds what the scene needs.
const WARM_UP_FRAMES: u32 = 3;

/// Times `args.frames` frames of `scene` after [`WARM_UP_FRAMES`].
fn time_frames(
    gpu: &Gpu,
    scene: Scene,
    mode: RenderMode,
    args: &BenchArgs,
) -> anyhow::Result<FrameStats> {
    let mut timed = TimedRenderer::new(gpu, scene, mode, args)?;
    let mut times = Vec::new();
    let mut passes = PassStats::new(args.pass_stat);
    for i in 0..args.frames + WARM_UP_FRAMES {
        let (ms, pass_times) = timed.frame(gpu)?;
        if i < WARM_UP_FRAMES {
            continue;
        }
        times.push(ms);
        passes.add(&pass_times);
    }
    let mean = times.iter().sum::<f64>() / times.len() as f64;
    times.sort_by(f64::total_cmp);
    Ok(FrameStats {
        mean,
        median: times[times.len() / 2],
        passes: passes.summary(),
    })
}

/// GPU milliseconds per pass over the samples that timed it: the mean, or
/// the least.
struct PassStats {
    stat: PassStat,
    sums: Vec<(&'static str, f64, u32)>,
}

impl PassStats {
    fn new(stat: PassStat) -> PassStats {
        PassStats {
            stat,
            sums: Vec::new(),
        }
    }

    fn add(&mut self, pass_times: &[(&'static str, f64)]) {
        for &(name, ms) in pass_times {
            match self.sums.iter_mut().find(|(n, _, _)| *n == name) {
                Some((_, least, _)) if self.stat == PassStat::Min => *least = least.min(ms),
                Some((_, sum, count)) => {
                    *sum += ms;
                    *count += 1;
                }
                None => self.sums.push((name, ms, 1)),
            }
        }
    }

    fn summary(&self) -> Vec<(&'static str, f64)> {
        self.sums
            .iter()
            .map(|&(name, sum, count)| (name, sum / f64::from(count)))
            .collect()
    }
}

impl FrameStats {
    fn kernels(&self) -> Vec<(&str, f64)> {
        self.passes.iter().map(|(n, ms)| (*n, *ms)).collect()
    }
}

fn pass_ms(stats: &FrameStats, name: &str) -> f64 {
    stats
        .passes
        .iter()
        .find(|(n, _)| *n == name)
        .map_or(f64::NAN, |(_, ms)| *ms)
}

/// The accumulate pass with its tile marks: the tables' "outline +
/// accumulate". Each span runs only where it is needed (the marks where
/// the scene has outlines, the accumulate pass unless the trace pass added
/// every pixel itself), so the spans a frame lacks count 0.
fn outline_accumulate_ms(stats: &FrameStats) -> f64 {
    ["outline_tiles", "accumulate"]
        .map(|name| pass_ms(stats, name))
        .iter()
        .filter(|ms| !ms.is_nan())
        .sum()
}

/// `base`'s first instance repeated on a square grid of `count`, camera
/// framing all of it.
fn grid(base: &Scene, count: usize, spacing_factor: f32) -> Scene {
    let mut scene = base.clone();
    let template = scene.instances[0].clone();
    let (lo, hi) = base.bounds();
    let spacing = (hi - lo).max_element() * spacing_factor;
    let side = (count as f32).sqrt().ceil() as usize;
    scene.instances = (0..count)
        .map(|i| {
            let offset = Vec3::new((i % side) as f32, 0.0, (i / side) as f32) * spacing;
            Instance {
                world_from_object: Mat4::from_translation(offset) * template.world_from_object,
                ..template.clone()
            }
        })
        .collect();
    let (lo, hi) = scene.bounds();
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    scene.camera.target = centre;
    scene.camera.eye = centre + Vec3::new(0.6, 0.8, 1.0).normalize() * radius * 1.9;
    scene
}

fn mesh_scene(path: &std::path::Path, camera: &str, args: &BenchArgs) -> anyhow::Result<Scene> {
    let ron = format!(
        r#"(version: 1,
            camera: ({camera}, width: {w}, height: {h}),
            lights: [Directional(direction: (-0.4, -1.0, -0.5), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: {{ "toon": (base_color: (0.7, 0.6, 0.5), model: Toon(bands: 4)) }},
            shapes: {{ "mesh": Mesh(path: {path:?}) }},
            instances: [(shape: "mesh", material: "toon")],
        )"#,
        w = args.width,
        h = args.height,
        path = path.display().to_string(),
    );
    Ok(Scene::from_ron_str(
        &ron,
        "bench",
        std::path::Path::new("."),
    )?)
}

fn triangles(scene: &Scene) -> usize {
    scene
        .instances
        .iter()
        .map(|i| match &scene.shapes[i.shape] {
            celray::scene::Shape::Mesh(m) => m.triangle_count(),
            other => celray::scene::tessellate(other).triangle_count(),
        })
        .sum()
}

/// Spot (the shipped cow mesh) alone, seen from the front: instanced on a
/// grid by the ray and acceleration suites.
fn spot_scene(args: &BenchArgs) -> anyhow::Result<Scene> {
    let spot_path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/models/spot/spot_triangulated.obj");
    mesh_scene(
        &spot_path,
        "eye: (0.0, 1.0, 3.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0",
        args,
    )
}

/// `n` toon-shaded spheres on a grid filling the view, lit by one
/// directional light: the instance-scaling scenes.
fn ball_grid(args: &BenchArgs, n: usize) -> anyhow::Result<Scene> {
    let ron = format!(
        r#"(version: 1,
            camera: (eye: (0.0, 3.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: {w}, height: {h}),
            lights: [Directional(direction: (-0.4, -1.0, -0.5), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: {{ "m": (base_color: (0.8, 0.3, 0.2), model: Toon(bands: 4)) }},
            shapes: {{ "ball": Sphere(radius: 0.45) }},
            instances: [(shape: "ball", material: "m")],
        )"#,
        w = args.width,
        h = args.height
    );
    let ball = Scene::from_ron_str(&ron, "bench", std::path::Path::new("."))?;
    Ok(grid(&ball, n, 1.1))
}

fn raster_suite(
    gpu: &Gpu,
    args: &BenchArgs,
    helmet: Option<&Scene>,
    r: &Report,
) -> anyhow::Result<()> {
    md!(
        r,
        "\n## Raster and hybrid frames ({}x{}, ms per frame)\n",
        args.width,
        args.height
    );
    md!(r, "| case | mode | frame ms (mean) | median | GPU raster | GPU trace | GPU outline + accumulate | triangles |");
    md!(r, "|---|---|---|---|---|---|---|---|");
    let row =
        |name: &str, scene: Scene, mode: RenderMode, case: Option<&str>| -> anyhow::Result<()> {
            let tris = triangles(&scene);
            let s = time_frames(gpu, scene, mode, args)?;
            if let Some(case) = case {
                let mut kernels = s.kernels();
                if mode == RenderMode::Raster {
                    // Raster mode runs no trace pass: its timer slot is stale.
                    kernels.retain(|(k, _)| *k != "trace");
                }
                r.case(case, s.mean, None, &kernels);
            }
            // Raster mode runs no trace pass, raytrace mode no raster pass.
            let ms_or_dash = |pass: &str, runs: bool| match runs {
                true => format!("{:.1}", pass_ms(&s, pass)),
                false => "-".to_string(),
            };
            let raster = ms_or_dash("raster", mode != RenderMode::Raytrace);
            let trace = ms_or_dash("trace", mode != RenderMode::Raster);
            md!(
                r,
                "| {name} | {} | {:.1} | {:.1} | {raster} | {trace} | {:.1} | {tris} |",
                mode.name(),
                s.mean,
                s.median,
                outline_accumulate_ms(&s)
            );
            Ok(())
        };
    for mode in RenderMode::ALL {
        let case = format!("default_{}", mode.name());
        row("default scene", Scene::builtin_default(), mode, Some(&case))?;
    }
    // Wide outlines: the accumulate pass searches a 17 x 17 neighbourhood
    // (MAX_OUTLINE_RADIUS 8) wherever a tile holds an outlined object.
    let mut wide = Scene::builtin_default();
    for m in wide
        .materials
        .iter_mut()
        .filter(|m| m.outline_width_px > 0.0)
    {
        m.outline_width_px = 8.0;
    }
    row(
        "default scene, outlines 8 px",
        wide,
        RenderMode::Raster,
        Some("outline_8px_raster"),
    )?;
    if let Some(helmet) = helmet {
        row(
            "FlightHelmet, anchor camera",
            helmet.clone(),
            RenderMode::Raster,
            Some("helmet_raster"),
        )?;
        for n in [1, 10, 100] {
            row(
                &format!("FlightHelmet x{n}"),
                grid(helmet, n, 1.2),
                RenderMode::Raster,
                None,
            )?;
        }
    }
    Ok(())
}

/// One ray per pixel centre of sample 0's camera: what the ray cases trace.
pub(crate) fn primary_rays(renderer: &Renderer, w: u32, h: u32) -> Vec<GpuRay> {
    let cam = renderer.sample_camera(0);
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (o, d) = cam.pixel_ray((w, h), x, y);
            GpuRay {
                origin: o.extend(0.0).to_array(),
                dir: d.extend(3e38).to_array(),
            }
        })
        .collect()
}

/// A raytrace-mode renderer of `scene` at the bench size, one sample,
/// walking `accel`; how long building it took (ms); and its camera's
/// primary rays, one per pixel centre.
pub(crate) fn ray_renderer(
    gpu: &Gpu,
    scene: Scene,
    args: &BenchArgs,
    accel: AccelChoice,
) -> anyhow::Result<(Renderer, f64, Vec<GpuRay>)> {
    let settings = RenderSettings {
        width: args.width,
        height: args.height,
        spp: 1,
        mode: RenderMode::Raytrace,
        accel,
        ..RenderSettings::default()
    };
    let start = Instant::now();
    let renderer = Renderer::new(gpu, scene, settings)?;
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let rays = primary_rays(&renderer, args.width, args.height);
    Ok((renderer, build_ms, rays))
}

/// The best of 3 timings of `f`, after one untimed warm-up call.
pub(crate) fn best_of(mut f: impl FnMut() -> anyhow::Result<f64>) -> anyhow::Result<f64> {
    f()?;
    let mut best = f64::MAX;
    for _ in 0..3 {
        best = best.min(f()?);
    }
    Ok(best)
}

/// Closest-hit throughput of the primary rays of `scene`'s camera (one ray
/// per pixel centre, by the ray-batch kernel), and the trace pass's time in
/// raytrace mode (primary ray plus a shadow ray per lit hit).
fn ray_row(
    gpu: &Gpu,
    name: &str,
    case: &str,
    scene: Scene,
    args: &BenchArgs,
    r: &Report,
    export: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    let (mut renderer, build_ms, rays) =
        ray_renderer(gpu, scene.clone(), args, RenderSettings::default().accel)?;
    let batch = RayBatch::new(gpu)?;
    let buffers = renderer.scene_buffers();
    let mut hits = 0;
    let mut last = Vec::new();
    let best = best_of(|| {
        let (h, s) = batch.trace_timed(gpu, buffers, &rays)?;
        hits = h.iter().filter(|h| h.instance != u32::MAX).count();
        last = h;
        Ok(s)
    })?;
    if let Some(path) = export {
        export::write_rays(path, &scene, &rays, &last)?;
        md!(
            r,
            "wrote {}'s triangles, rays and hits to {}",
            case,
            path.display()
        );
    }
    let accel = &buffers.accel;
    let bytes = accel.nodes.len() * 32
        + accel.triangles.len() * 96
        + accel.tlas_items.len() * 4
        + scene.instances.len() * 208;
    renderer.render_sample(gpu)?;
    renderer.enable_pass_timing(gpu);
    let mut trace_ms = f64::MAX;
    for _ in 0..3 {
        renderer.reset();
        renderer.render_sample(gpu)?;
        trace_ms = trace_ms.min(pass_ms(
            &FrameStats {
                mean: 0.0,
                median: 0.0,
                passes: renderer.pass_times(gpu)?,
            },
            "trace",
        ));
    }
    let shadow_rays = hits; // one sun, one shadow ray per hit facing it (upper bound)
    r.case(
        case,
        best * 1e3,
        Some(rays.len() as f64 / best / 1e6),
        &[("ray_batch", best * 1e3), ("trace", trace_ms)],
    );
    md!(
        r,
        "| {name} | {} | {:.1}% | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
        scene.instances.len(),
        100.0 * hits as f64 / rays.len() as f64,
        rays.len() as f64 / best / 1e6,
        trace_ms,
        (rays.len() + shadow_rays) as f64 / (trace_ms * 1e-3) / 1e6,
        build_ms,
        bytes as f64 / (1024.0 * 1024.0),
    );
    Ok(())
}

/// Issue 9's question for a wavefront split: would the shadow rays cost
/// less in a kernel of their own, over a compacted queue, than inside the
/// fused trace kernel? The default scene in raytrace mode. The fused
/// kernel's shadow share is its trace pass with shadows less the same pass
/// with every light's `cast_shadows` off (a variant without the shadow
/// code). The split's shadow stage is the same rays (from each primary hit,
/// facing normal, towards each shadow-casting light it faces, the trace
/// pass's epsilon), already compacted into one buffer, through the any-hit
/// ray-batch kernel: a lower bound on that stage, before any queue is
/// built or read back into the shading. Both walk celray's own BVH. (The
/// batch's rays face the hit's shading normal where the trace pass uses
/// the geometric one to flip it: they differ only at the cow's silhouette.)
fn shadow_split_row(gpu: &Gpu, args: &BenchArgs, r: &Report) -> anyhow::Result<()> {
    let scene = Scene::builtin_default();
    let args = &BenchArgs {
        accel: AccelChoice::Software,
        ..args.clone()
    };
    let fused = time_frames(gpu, scene.clone(), RenderMode::Raytrace, args)?;
    let mut unshadowed = scene.clone();
    for light in &mut unshadowed.lights {
        *light.cast_shadows_mut() = false;
    }
    let no_shadows = time_frames(gpu, unshadowed, RenderMode::Raytrace, args)?;
    let (renderer, _, rays) = ray_renderer(gpu, scene.clone(), args, AccelChoice::Software)?;
    let buffers = renderer.scene_buffers();
    let hits = RayBatch::new(gpu)?.trace(gpu, buffers, &rays)?;
    let (lo, hi) = scene.bounds();
    let epsilon = ((hi - lo).length() * 0.5).max(1e-3) * 1e-4;
    let mut shadow = Vec::new();
    for (ray, hit) in rays
        .iter()
        .zip(&hits)
        .filter(|(_, h)| h.instance != u32::MAX)
    {
        let d = Vec3::from_slice(&ray.dir[..3]);
        let p = Vec3::from_slice(&ray.origin[..3]) + d * hit.t;
        let mut n = Vec3::from(hit.normal);
        if n.dot(d) > 0.0 {
            n = -n;
        }
        for light in &scene.lights {
            let (to_light, distance) = match *light {
                Light::Directional {
                    direction,
                    cast_shadows: true,
                    ..
                } => (-direction, 3.0e38),
                Light::Point {
                    position,
                    cast_shadows: true,
                    ..
                } => ((position - p).normalize(), (position - p).length()),
                _ => continue,
            };
            if n.dot(to_light) > 0.0 {
                shadow.push(GpuRay {
                    origin: (p + n * epsilon).extend(0.0).to_array(),
                    dir: to_light.extend(distance).to_array(),
                });
            }
        }
    }
    let batch = RayBatch::any_hit(gpu)?;
    let batch_s = best_of(|| Ok(batch.trace_timed(gpu, buffers, &shadow)?.1))?;
    let (with_ms, without_ms) = (pass_ms(&fused, "trace"), pass_ms(&no_shadows, "trace"));
    r.case(
        "shadow_split",
        batch_s * 1e3,
        Some(shadow.len() as f64 / batch_s / 1e6),
        &[
            ("trace", with_ms),
            ("trace_without_shadows", without_ms),
            ("shadow_batch", batch_s * 1e3),
        ],
    );
    md!(
        r,
        "\nShadow rays of the default scene (raytrace): in the fused trace kernel {:.1} ms (trace {:.1} less {:.1} without shadows); {} of them compacted into one any-hit batch {:.1} ms.",
        with_ms - without_ms,
        with_ms,
        without_ms,
        shadow.len(),
        batch_s * 1e3
    );
    Ok(())
}

/// The scenes of `bench rays --compare-shaders`: the ray cases' own
/// (helmet_rays skipped, with a line saying so, without the models).
fn ray_ab_cases(
    args: &BenchArgs,
    helmet: Option<Scene>,
    r: &Report,
) -> anyhow::Result<Vec<(&'static str, Scene)>> {
    let mut cases = Vec::new();
    match helmet {
        Some(helmet) => cases.push(("helmet_rays", helmet)),
        None => r.skipped("helmet_rays", &missing_helmet(args)),
    }
    cases.push(("spot_10000_rays", grid(&spot_scene(args)?, 10_000, 1.1)));
    cases.push(("spheres_100_rays", ball_grid(args, 100)?));
    Ok(cases)
}

fn rays_suite(
    gpu: &Gpu,
    args: &BenchArgs,
    helmet: Option<&Scene>,
    r: &Report,
) -> anyhow::Result<()> {
    md!(
        r,
        "\n## Ray throughput ({}x{}, one primary ray per pixel)\n",
        args.width,
        args.height
    );
    md!(r, "| scene | instances | rays hitting | closest-hit Mrays/s | trace pass ms (primary + shadow + shading) | primary+shadow Mrays/s | upload + BVH build ms | BVH + instance MiB |");
    md!(r, "|---|---|---|---|---|---|---|---|");
    if let Some(helmet) = helmet {
        ray_row(
            gpu,
            "FlightHelmet, anchor camera",
            "helmet_rays",
            helmet.clone(),
            args,
            r,
            args.export_rays.as_deref(),
        )?;
    } else if args.export_rays.is_some() {
        anyhow::bail!(
            "--export-rays exports helmet_rays: {}",
            missing_helmet(args)
        );
    } else {
        r.skipped("helmet_rays", &missing_helmet(args));
    }
    ray_row(
        gpu,
        "spot x 10,000",
        "spot_10000_rays",
        grid(&spot_scene(args)?, 10_000, 1.1),
        args,
        r,
        None,
    )?;
    let ball = |n: usize| ball_grid(args, n);
    ray_row(
        gpu,
        "100 analytic spheres",
        "spheres_100_rays",
        ball(100)?,
        args,
        r,
        None,
    )?;
    shadow_split_row(gpu, args, r)?;

    md!(
        r,
        "\n## Instance scaling: n spheres on a grid filling the view, raytrace mode\n"
    );
    md!(
        r,
        "| instances | trace pass ms | vs 1 instance | BVH + instance MiB |"
    );
    md!(r, "|---|---|---|---|");
    let mut first = None;
    for n in [1usize, 10, 100, 1_000, 10_000, 100_000] {
        let scene = ball(n)?;
        let s = time_frames(
            gpu,
            scene.clone(),
            RenderMode::Raytrace,
            &BenchArgs {
                // The cases with targets (one_sphere_raytrace, and
                // instances_100000 against instances_1) take the full
                // count: with 5 frames the single sphere's mean moved
                // 14% between two runs. The steps between, 5 each.
                frames: if n == 1 || n == 100_000 {
                    args.frames
                } else {
                    args.frames.min(5)
                },
                ..args.clone()
            },
        )?;
        let trace = pass_ms(&s, "trace");
        let base = *first.get_or_insert(trace);
        if n == 1 {
            r.case("one_sphere_raytrace", s.mean, None, &s.kernels());
        }
        r.case(&format!("instances_{n}"), s.mean, None, &s.kernels());
        let small = Renderer::new(
            gpu,
            scene,
            RenderSettings {
                width: 8,
                height: 8,
                ..Default::default()
            },
        )?;
        let a = &small.scene_buffers().accel;
        let bytes = a.nodes.len() * 32 + a.triangles.len() * 96 + a.tlas_items.len() * 4 + n * 208;
        md!(
            r,
            "| {n} | {trace:.1} | {:.2}x | {:.2} |",
            trace / base,
            bytes as f64 / (1024.0 * 1024.0)
        );
    }
    Ok(())
}

/// Time per accumulated sample (all passes, hybrid mode) with each effect.
fn effects_suite(gpu: &Gpu, args: &BenchArgs, r: &Report) -> anyhow::Result<()> {
    md!(
        r,
        "\n## Time per accumulated sample ({}x{}, hybrid mode)\n",
        args.width,
        args.height
    );
    md!(r, "| scene | effect | ms per sample (mean) | median | GPU raster | GPU trace | GPU outline + accumulate |");
    md!(r, "|---|---|---|---|---|---|---|");
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let default = Scene::builtin_default();
    let mut dof = default.clone();
    dof.camera.aperture_radius = 0.08;
    let mut motion = default.clone();
    if let Some(inst) = motion.instances.get_mut(2) {
        inst.world_from_object_end =
            Some(Mat4::from_translation(Vec3::new(0.6, 0.0, 0.0)) * inst.world_from_object);
    }
    let cases = [
        (
            "default",
            "anti-aliasing only",
            "effects_default",
            default.clone(),
        ),
        (
            "default",
            "+ depth of field (disk, r = 0.08)",
            "effects_dof",
            dof,
        ),
        (
            "default",
            "+ motion blur (one moving sphere)",
            "effects_motion",
            motion,
        ),
        (
            "mirrors.ron",
            "mirror + glossy reflections, shadows",
            "mirrors",
            Scene::load(&dir.join("mirrors.ron"))?,
        ),
        (
            "anchor_dof_motion.ron",
            "depth of field + motion blur (anchor scene 2)",
            "anchor_dof_motion",
            Scene::load(&dir.join("anchor_dof_motion.ron"))?,
        ),
        (
            "textured_models.ron",
            "base-colour maps (helmet, fox, spot) + checker floor",
            "textured_models",
            Scene::load(&dir.join("textured_models.ron"))?,
        ),
    ];
    for (name, effect, case, scene) in cases {
        let st = time_frames(gpu, scene, RenderMode::Hybrid, args)?;
        r.case(case, st.mean, None, &st.kernels());
        md!(
            r,
            "| {name} | {effect} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            st.mean,
            st.median,
            pass_ms(&st, "raster"),
            pass_ms(&st, "trace"),
            outline_accumulate_ms(&st)
        );
    }
    temporal_rows(gpu, args, r)
}

/// The reproject pass's cost: the default scene orbiting 0.5 degrees a
/// frame, one sample per frame, temporal reprojection on (every frame a
/// moving one) against off.
fn temporal_rows(gpu: &Gpu, args: &BenchArgs, r: &Report) -> anyhow::Result<()> {
    md!(
        r,
        "\n## Temporal reprojection while the camera orbits ({}x{}, hybrid, default scene)\n",
        args.width,
        args.height
    );
    md!(r,"| temporal | ms per frame (mean) | GPU raster | GPU trace | GPU outline + accumulate | GPU reproject |");
    md!(r, "|---|---|---|---|---|---|");
    for temporal in [
        celray::render::Temporal::Off,
        celray::render::Temporal::Reproject,
    ] {
        let scene = Scene::builtin_default();
        let settings = RenderSettings {
            width: args.width,
            height: args.height,
            temporal,
            ..RenderSettings::default()
        };
        let mut renderer = Renderer::new(gpu, scene.clone(), settings)?;
        renderer.enable_pass_timing(gpu);
        let (mut wall, mut passes) = (0.0, PassStats::new(args.pass_stat));
        for i in 0..args.frames + 3 {
            let mut camera = scene.camera.clone();
            let turn = glam::Quat::from_rotation_y((0.5 * i as f32).to_radians());
            camera.eye = camera.target + turn * (camera.eye - camera.target);
            renderer.set_camera(camera);
            let start = Instant::now();
            renderer.render_sample(gpu)?;
            gpu.wait_idle()?;
            let pass_times = renderer.pass_times(gpu)?;
            if i < 3 {
                continue;
            }
            wall += start.elapsed().as_secs_f64() * 1e3 / f64::from(args.frames);
            passes.add(&pass_times);
        }
        let st = FrameStats {
            mean: wall,
            median: wall,
            passes: passes.summary(),
        };
        r.case(
            &format!("temporal_{}", temporal.name()),
            st.mean,
            None,
            &st.kernels(),
        );
        md!(
            r,
            "| {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            temporal.name(),
            st.mean,
            pass_ms(&st, "raster"),
            pass_ms(&st, "trace"),
            outline_accumulate_ms(&st),
            pass_ms(&st, "reproject")
        );
    }
    Ok(())
}

/// Samples and seconds each pattern needs for a FLIP mean of 0.02 against a
/// 1024-sample jittered reference, on the 1D zone plate of `celray
/// experiment sampling` (256 x 256, raster mode): fine bars make the
/// patterns differ, where a mostly flat toon scene passes at one sample.
fn flip_convergence(gpu: &Gpu, r: &Report) -> anyhow::Result<()> {
    md!(r, "\n## Samples to reach FLIP mean 0.02 (1D zone plate, raster mode, 256x256, vs 1024 jittered samples)\n");
    md!(
        r,
        "| pattern | samples | seconds | FLIP mean at that count |"
    );
    md!(r, "|---|---|---|---|");
    let scene = crate::experiment::zone_plate_scene(256)?;
    let settings = |pattern, spp| RenderSettings {
        width: 256,
        height: 256,
        spp,
        pattern,
        mode: RenderMode::Raster,
        ..RenderSettings::default()
    };
    let reference = celray::capture::render_frame(
        gpu,
        scene.clone(),
        settings(celray::sampling::PixelPattern::Jittered, 1024),
        false,
        |_, _| {},
    )?;
    for pattern in celray::sampling::PixelPattern::ALL {
        let mut found = None;
        for spp in [1u32, 2, 4, 8, 16, 32, 64, 128, 256, 512] {
            let start = Instant::now();
            let frame = celray::capture::render_frame(
                gpu,
                scene.clone(),
                settings(pattern, spp),
                false,
                |_, _| {},
            )?;
            let seconds = start.elapsed().as_secs_f64();
            let flip = celray::compare::flip_mean(&reference, &frame);
            if flip <= 0.02 {
                found = Some((spp, seconds, flip));
                break;
            }
        }
        match found {
            Some((spp, seconds, flip)) => {
                md!(
                    r,
                    "| {} | {spp} | {seconds:.2} | {flip:.4} |",
                    pattern.name()
                )
            }
            None => md!(r, "| {} | > 512 | - | - |", pattern.name()),
        }
    }
    Ok(())
}

fn missing_helmet(args: &BenchArgs) -> String {
    format!(
        "FlightHelmet not found at {} (pass --models DIR, the folder of the shared test models)",
        args.models.join("FlightHelmet/FlightHelmet.gltf").display()
    )
}

/// The fewest dispatches the floor kernel's median is taken over.
const MIN_FLOOR_FRAMES: u32 = 20;

/// Times the floor kernel against 1 and 64 spheres and records floor_1 as
/// the denominator of every floor_ratio of this run.
fn floor_suite(gpu: &Gpu, args: &BenchArgs, r: &mut Report) -> anyhow::Result<()> {
    md!(
        r,
        "\n## Floor kernel ({}x{}: primary + shadow ray per pixel, brute force against N spheres)\n",
        args.width,
        args.height
    );
    md!(r, "| case | GPU ms (median) |");
    md!(r, "|---|---|");
    for n in [1u32, 64] {
        // Every ratio divides by floor_1, a few milliseconds long: its
        // median over 5 dispatches moved by up to 2x between runs on a
        // quiet machine, over 20 by under 2%. So never fewer than 20.
        let frames = args.frames.max(MIN_FLOOR_FRAMES);
        let ms = floor::floor_ms(gpu, args.width, args.height, n, frames)?;
        if n == 1 {
            r.floor_1 = Some(ms);
        }
        let case = format!("floor_{n}");
        r.case(&case, ms, None, &[("floor", ms)]);
        md!(r, "| {case} | {ms:.2} |");
    }
    Ok(())
}

/// Suite `scene`: frames of the user's own scene (case `scene`).
fn scene_case(
    gpu: &Gpu,
    args: &BenchArgs,
    (path, scene): (&std::path::Path, Scene),
    r: &Report,
) -> anyhow::Result<()> {
    let s = time_frames(gpu, scene, args.mode, args)?;
    md!(
        r,
        "\n## {} ({}x{}, {} mode)\n",
        path.display(),
        args.width,
        args.height,
        args.mode.name()
    );
    md!(r, "| frame ms (mean) | median | GPU ms per pass |");
    md!(r, "|---|---|---|");
    let mut kernels = s.kernels();
    if args.mode == RenderMode::Raster {
        // Raster mode runs no trace pass: its timer slot is stale.
        kernels.retain(|(k, _)| *k != "trace");
    }
    let passes: Vec<String> = kernels
        .iter()
        .map(|(k, ms)| format!("{k} {ms:.1}"))
        .collect();
    md!(
        r,
        "| {:.1} | {:.1} | {} |",
        s.mean,
        s.median,
        passes.join(", ")
    );
    r.case("scene", s.mean, None, &kernels);
    Ok(())
}

pub fn run(gpu: &Gpu, args: &BenchArgs) -> anyhow::Result<()> {
    if let Some(dir) = &args.shaders {
        if !dir.is_dir() {
            anyhow::bail!("--shaders {}: not a folder", dir.display());
        }
        gpu.set_shader_overrides(Some(ShaderOverrides::read_given_dir(dir, "--shaders")?));
    }
    if let Some(dir) = &args.compare_shaders {
        if !dir.is_dir() {
            anyhow::bail!("--compare-shaders {}: not a folder", dir.display());
        }
    }
    if args.frames == 0 {
        anyhow::bail!("--frames must be at least 1 (frames timed per case)");
    }
    gpu.set_uniform_tables(!args.storage_tables);
    // Suite `scene`: the file is read (and refused) before anything runs.
    let own_scene = match (args.suite.as_str(), &args.scene) {
        ("scene", Some(path)) => Some((path.as_path(), Scene::load(path)?)),
        ("scene", None) => anyhow::bail!("bench scene: name the scene file with --scene FILE"),
        ("rays", None) => None,
        (_, _) if args.compare_shaders.is_some() => anyhow::bail!(
            "--compare-shaders is for the suites `scene` (celray bench scene --scene FILE --compare-shaders DIR) and `rays`"
        ),
        (_, Some(_)) => {
            anyhow::bail!("--scene is for the suite `scene` (celray bench scene --scene FILE)")
        }
        (_, None) => None,
    };
    if let Some(path) = &args.export_rays {
        export::check_target(path, &args.suite)?;
    }
    let mut report = Report {
        json: args.json,
        driver: format!("{} {}", gpu.summary.name, gpu.summary.driver),
        floor_1: None,
    };
    md!(report, "adapter: {}", gpu.summary);
    let helmet_path = args.models.join("FlightHelmet/FlightHelmet.gltf");
    let helmet = if helmet_path.exists() {
        let camera = "eye: (0.60609, 0.74952, 1.58035), target: (-0.02035, 0.35799, 0.01424), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0";
        Some(mesh_scene(&helmet_path, camera, args)?)
    } else {
        md!(report, "{}: its cases are skipped", missing_helmet(args));
        None
    };
    floor_suite(gpu, args, &mut report)?;
    let r = &report;
    match args.suite.as_str() {
        "floor" => Ok(()),
        "raster" => raster_suite(gpu, args, helmet.as_ref(), r),
        "rays" => match &args.compare_shaders {
            Some(dir) => ab::compare_ray_shaders(gpu, args, ray_ab_cases(args, helmet, r)?, dir, r),
            None => rays_suite(gpu, args, helmet.as_ref(), r),
        },
        "effects" => {
            effects_suite(gpu, args, r)?;
            flip_convergence(gpu, r)
        }
        "csg" => csg::csg_suite(gpu, args, r),
        "accel" => accel::accel_suite(gpu, args, helmet.as_ref(), r),
        "temporal" => temporal_rows(gpu, args, r),
        "scene" => {
            let own_scene = own_scene.expect("loaded above");
            match &args.compare_shaders {
                Some(dir) => ab::compare_shaders(gpu, args, own_scene, dir, r),
                None => scene_case(gpu, args, own_scene, r),
            }
        }
        "all" => {
            raster_suite(gpu, args, helmet.as_ref(), r)?;
            rays_suite(gpu, args, helmet.as_ref(), r)?;
            effects_suite(gpu, args, r)?;
            flip_convergence(gpu, r)?;
            csg::csg_suite(gpu, args, r)?;
            accel::accel_suite(gpu, args, helmet.as_ref(), r)
        }
        other => anyhow::bail!(
            "bench suite {other:?}: expected floor, raster, rays, effects, csg, accel, temporal, all or scene"
        ),
    }
}
