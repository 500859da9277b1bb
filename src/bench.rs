//! `celray bench`: frame times of the raster path, on whatever adapter is
//! chosen. Timings live here, never in tests.

use std::path::PathBuf;
use std::time::Instant;

use glam::{Mat4, Vec3};

use celray::gpu::Gpu;
use celray::render::{RenderSettings, Renderer};
use celray::scene::{Instance, Scene};

#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    /// Frames timed per case (after 3 warm-up frames).
    #[arg(long, default_value_t = 30)]
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
}

/// Milliseconds per frame: mean and median over `frames` frames, each one
/// sample (raster + accumulate) plus a resolve, waited for.
fn time_frames(gpu: &Gpu, scene: Scene, args: &BenchArgs) -> anyhow::Result<(f64, f64)> {
    let settings = RenderSettings {
        width: args.width,
        height: args.height,
        spp: 1 << 20,
        ..RenderSettings::default()
    };
    let mut renderer = Renderer::new(gpu, scene, settings)?;
    let resolve = renderer.new_resolve_pass(gpu, wgpu::TextureFormat::Rgba8UnormSrgb)?;
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
    let view = target.create_view(&Default::default());
    let timed = renderer.enable_pass_timing(gpu);
    let mut times = Vec::new();
    let mut pass_ms: Vec<(&str, f64)> = Vec::new();
    for i in 0..args.frames + 3 {
        let start = Instant::now();
        renderer.render_sample(gpu)?;
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        renderer.encode_resolve(&resolve, &mut encoder, &view);
        gpu.queue.submit([encoder.finish()]);
        gpu.wait_idle()?;
        if i >= 3 {
            times.push(start.elapsed().as_secs_f64() * 1e3);
            if timed {
                for (k, (name, ms)) in renderer.pass_times(gpu)?.into_iter().enumerate() {
                    if pass_ms.len() <= k {
                        pass_ms.push((name, 0.0));
                    }
                    pass_ms[k].1 += ms / f64::from(args.frames);
                }
            }
        }
    }
    let passes: Vec<String> = pass_ms
        .iter()
        .map(|(n, ms)| format!("{n} {ms:.1}"))
        .collect();
    log::warn!("GPU ms per pass: {}", passes.join(", "));
    let mean = times.iter().sum::<f64>() / times.len() as f64;
    times.sort_by(f64::total_cmp);
    Ok((mean, times[times.len() / 2]))
}

/// FlightHelmet instanced `count` times on a square grid, camera framing all.
fn helmet_grid(base: &Scene, count: usize) -> Scene {
    let mut scene = base.clone();
    let template = scene.instances[0].clone();
    let (lo, hi) = base.bounds();
    let spacing = (hi - lo).max_element() * 1.2;
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
    scene.camera.eye = centre + Vec3::new(0.6, 0.5, 1.0).normalize() * radius * 2.2;
    scene
}

pub fn run(gpu: &Gpu, args: &BenchArgs) -> anyhow::Result<()> {
    println!("adapter: {}", gpu.summary);
    println!(
        "{}x{}, {} frames per case; one frame = raster + outline/accumulate + resolve\n",
        args.width, args.height, args.frames
    );
    println!(
        "{:<40} {:>10} {:>10} {:>12}",
        "case", "mean ms", "median ms", "triangles"
    );
    let report = |name: &str, scene: Scene| -> anyhow::Result<()> {
        let tris: usize = scene
            .instances
            .iter()
            .map(|i| match &scene.shapes[i.shape] {
                celray::scene::Shape::Mesh(m) => m.triangle_count(),
                other => celray::scene::tessellate(other).triangle_count(),
            })
            .sum();
        let (mean, median) = time_frames(gpu, scene, args)?;
        println!("{name:<40} {mean:>10.2} {median:>10.2} {tris:>12}");
        Ok(())
    };
    report("default scene", Scene::builtin_default())?;

    let helmet = args.models.join("FlightHelmet/FlightHelmet.gltf");
    if !helmet.exists() {
        println!(
            "\nFlightHelmet not found at {}: skipping its cases (pass --models DIR, the folder of the shared test models)",
            helmet.display()
        );
        return Ok(());
    }
    let ron = format!(
        r#"(version: 1,
            camera: (eye: (0.60609, 0.74952, 1.58035), target: (-0.02035, 0.35799, 0.01424), up: (0.0, 1.0, 0.0), fov_y_deg: 40.0, width: {w}, height: {h}),
            lights: [Directional(direction: (-0.4, -1.0, -0.5), color: (1.0, 1.0, 1.0), intensity: 1.0)],
            materials: {{ "toon": (base_color: (0.7, 0.6, 0.5), model: Toon(bands: 4)) }},
            shapes: {{ "helmet": Mesh(path: {path:?}) }},
            instances: [(shape: "helmet", material: "toon")],
        )"#,
        w = args.width,
        h = args.height,
        path = helmet.display().to_string(),
    );
    let base = Scene::from_ron_str(&ron, "bench-flighthelmet", std::path::Path::new("."))?;
    report("FlightHelmet, anchor camera", base.clone())?;
    for n in [1, 10, 100] {
        report(&format!("FlightHelmet x{n}"), helmet_grid(&base, n))?;
    }
    Ok(())
}
